"""The strike scene: one stick on a fulcrum above one instrument, thrown onto it on schedule.

A test and integration scene (the first end-to-end strike): the stick hangs
in a fixed "hand" on a revolute fulcrum over the kit event's hit point (the
SNARE hit point by default). For a strike (time, velocity) the stick is
released ``lead_s`` before the contact time turning at the speed that brings
the tip onto the head at ``velocity`` m/s at that time; it then flies freely
(no torque), hits, rebounds off the compliant head, and a PD controller
catches it back to its rest angle. Only the contact comes from the
simulation; the release is kinematic.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from common.kit import EventType, Kit
from common.quiet_pybullet import pybullet as p
from services.physics.contacts import ContactTracker, Striker
from services.physics.kitbodies import KitBodies, build_kit, hihat_gap
from services.physics.sticks import StickSpec
from services.physics.urdf import Inertial, Joint, Link, Robot, load_robot
from services.physics.world import World

REST_ANGLE = 0.35
"""Stick angle between strokes, radians above the contact angle (tip about 9 cm up)."""

TILT_DEG = 12.0
"""Angle between the stick and the head at contact, degrees (the bead touches first)."""


@dataclass(frozen=True)
class Strike:
    """A scheduled strike: contact time (seconds, rig/simulation time) and tip speed (m/s)."""

    time: float
    velocity: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.time) and self.time >= 0):
            raise ValueError(f"strike time must be a finite time >= 0 seconds, got {self.time!r}")
        if not (math.isfinite(self.velocity) and 0 < self.velocity <= 30):
            raise ValueError(f"strike velocity must be in (0, 30] m/s, got {self.velocity!r}")


class StrikeScene:
    """One instrument from the kit and one stick on a fulcrum, driven by a strike schedule."""

    def __init__(self, world: World, kit: Kit, event: EventType = EventType.SNARE, lead_s: float = 0.01,
                 stick: StickSpec | None = None, period_s: float = 0.0, period_velocity: float = 3.0) -> None:
        self.world = world
        self.stick = stick or StickSpec()
        spec = kit.spec(event) if hasattr(kit, "spec") else kit.events[event]
        obj = kit.object(spec.object)
        self.instrument = obj.id
        self.kit_bodies: KitBodies = build_kit(world, kit, only={obj.id})
        hihat = self.kit_bodies.hihat
        if event == EventType.HIHATCLOSED and hihat is not None:
            # a closed hi-hat: its pedal held down from the start (at rest it stands open, its top above the
            # closed hit point the stick is aimed at, and the stick was released into the plate)
            self.kit_bodies.held_press = 1.0
            world.client.resetJointState(hihat.top_body, hihat.rod_joint,
                                         hihat_gap(1.0, hihat.rest_opening, hihat.closes_at))
        self.lead_s = lead_s
        self.pending: list[Strike] = []
        self._free_until = -1.0
        self.released = 0
        self.period_s = period_s
        """Strike every period_s seconds (0: only scheduled strikes)."""
        self.period_velocity = period_velocity
        self._next_periodic = period_s

        # hit point and a frame for the stick: d in the head plane pointing away from the drummer
        n = np.asarray(obj.normal())
        r = spec.r * obj.radius
        rot = np.asarray(p.getMatrixFromQuaternion(p.getQuaternionFromEuler(
            [math.radians(a) for a in obj.rotation_deg]))).reshape(3, 3)
        hit = np.asarray(obj.position) + rot @ np.array([r * math.cos(spec.theta), r * math.sin(spec.theta), 0.0])
        away = np.array([0.0, 1.0, 0.0]) - n * n[1]
        if np.linalg.norm(away) < 1e-6:  # a head facing the drummer (kick): come from above
            away = np.array([0.0, 0.0, -1.0]) - n * n[2]
        d = away / np.linalg.norm(away)
        tilt = math.radians(TILT_DEG)
        reach = self.stick.tip_offset
        y_axis = d * math.cos(tilt) - n * math.sin(tilt)
        x_axis = np.cross(d, n)
        x_axis /= np.linalg.norm(x_axis)
        z_axis = np.cross(x_axis, y_axis)
        tip_at_contact = hit + n * self.stick.tip_radius_m
        fulcrum = tip_at_contact - y_axis * reach
        basis = np.column_stack([x_axis, y_axis, z_axis])
        quat = _quat_from_matrix(basis)
        self.hit_point = hit
        self.reach = reach

        robot = Robot("strike_stick")
        robot.add_link(Link("hand", Inertial(0.0)))
        self.stick.add_to(robot, "right_stick", "hand", Joint(
            "fulcrum", "revolute", "hand", "right_stick", axis=(1, 0, 0), lower=-1.0, upper=1.5, effort=50,
            velocity=200))
        self.body = load_robot(world.client, robot, tuple(fulcrum), quat, fixed_base=True,
                               flags=p.URDF_USE_INERTIA_FROM_FILE)
        c = world.client
        c.setJointMotorControl2(self.body, 0, p.VELOCITY_CONTROL, force=0.0)
        c.changeDynamics(self.body, 0, linearDamping=0.0, angularDamping=0.0)
        c.resetJointState(self.body, 0, REST_ANGLE, 0.0)
        self.tracker = ContactTracker(world, self.kit_bodies)
        self.tracker.add_striker(Striker(self.body, 0, "right_stick", stick=self.stick, side="right"))
        self.pose_links: list[tuple[str, int, int]] = [
            ("right_stick", self.body, 0),
            ("right_stick_tip", self.body, 1),
            *self.kit_bodies.pose_links,
        ]

    def schedule(self, strikes: list[Strike]) -> None:
        """Add strikes (kept sorted by time)."""
        self.pending = sorted([*self.pending, *strikes], key=lambda s: (s.time, s.velocity))

    def reset(self) -> None:
        self.pending.clear()
        self._free_until = -1.0
        self.world.client.resetJointState(self.body, 0, REST_ANGLE, 0.0)

    def pre_step(self, t_next: float) -> None:
        """Prepare the step that ends at simulation time ``t_next`` seconds."""
        c = self.world.client
        dt = self.world.dt
        if self.period_s > 0 and self._next_periodic - self.lead_s <= t_next:
            if self._next_periodic - self.lead_s < t_next - dt:  # joined late (live): next one from now
                self._next_periodic = t_next + self.lead_s
            self.schedule([Strike(self._next_periodic, self.period_velocity)])
            self._next_periodic += self.period_s
        while self.pending and self.pending[0].time - self.lead_s <= t_next - dt + 1e-12:
            strike = self.pending.pop(0)
            lead = max(strike.time - (t_next - dt), 0.0)
            omega = strike.velocity / self.reach
            # gravity speeds the fall a little over the lead; aim slightly high so contact lands on time
            c.resetJointState(self.body, 0, omega * lead, -omega)
            self._free_until = strike.time + 0.03
            self.released += 1
        if t_next <= self._free_until:
            torque = 0.0
        else:
            q, qd = c.getJointState(self.body, 0)[:2]
            torque = 2.0 * (REST_ANGLE - q) - 0.08 * qd
        c.setJointMotorControl2(self.body, 0, p.TORQUE_CONTROL, force=torque)
        self.kit_bodies.pre_step(self.world)


def _quat_from_matrix(m: np.ndarray) -> tuple[float, float, float, float]:
    """Quaternion (x, y, z, w) of a rotation matrix (columns = the frame's axes in world)."""
    from scipy.spatial.transform import Rotation

    q = Rotation.from_matrix(m).as_quat()
    return (float(q[0]), float(q[1]), float(q[2]), float(q[3]))
