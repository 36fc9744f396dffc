"""The drum kit as PyBullet bodies, built from the shared kit description (common/kit.py).

* membranes (snare, toms, kick) and the cowbell: static bodies whose frame is
  the kit object's frame (local +z = playing surface normal, origin = centre of
  the head); the shell is a cylinder behind the head.
* cymbals: a fixed mount and the cymbal on a two-axis spring hinge (two
  revolute joints, explicit spring-damper torques), so a struck cymbal swings
  and settles (Kragtwijk's eta^t alpha sin(beta t)).
* hi-hat: the bottom cymbal is static; the top cymbal rides a prismatic rod
  whose opening follows the hi-hat pedal's footboard angle. The top closing on
  the bottom is a contact (part ``hihat_top``, instrument ``hihat``).
* pedals: a footboard on a heel hinge with a return spring; the kick pedal's
  beater is geared to its footboard (a gear constraint), so pressing the
  footboard swings the beater into the kick head. A double pedal adds a second
  footboard and beater for the other foot.
* throne and stands: static; stands are visual only (no collision).

Contact compliance (stiffness, damping) is set per instrument from its kind
and elasticity (see :func:`contact_parameters`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from common.kit import (
    BEATER_REST_RAD,
    FOOTBOARD_LENGTH_M,
    HIHAT_CLOSED_GAP_M,
    PEDAL_REST_ANGLE_RAD,
    STAND_ROD_RADIUS_M,
    Beater,
    Kit,
    KitObject,
    kit_hardware,
    stand_rods,
)
from common.quiet_pybullet import pybullet as p
from services.physics.urdf import Inertial, Joint, Link, Robot, Shape, cylinder_inertia, load_robot
from services.physics.world import World, quat_from_rpy_deg, rotation_matrix

CYMBAL_DENSITY = 8600.0 * 0.6
"""Effective cymbal density, kg/m^3: B20 bronze (8600) times 0.6 for the taper of a real cymbal."""

HIHAT_MAX_GAP_M = 0.025
"""Gap between the hi-hat cymbals at opening 1, metres."""

PEDAL_REST_ANGLE = PEDAL_REST_ANGLE_RAD
"""Footboard angle at rest above the floor plate, radians (0: pressed flat); the kit model's (common/kit.py)."""

PEDAL_SPRING_NM_PER_RAD = 40.0
"""Return spring of a footboard, N m/rad."""

_SILVER = (0.75, 0.75, 0.78, 1.0)
_BRASS = (0.85, 0.68, 0.25, 1.0)
_HEAD = (0.95, 0.94, 0.9, 1.0)
_DARK = (0.15, 0.15, 0.17, 1.0)


@dataclass(frozen=True)
class ContactParameters:
    """Compliant contact: stiffness N/m, damping N s/m, friction coefficient."""

    stiffness: float
    damping: float
    friction: float = 0.5


def contact_parameters(obj: KitObject) -> ContactParameters:
    """Per-instrument compliant contact parameters from the object's kind and elasticity.

    Membranes are soft (a head deflects a few millimetres under a stick), metal
    is stiffer. Elasticity (0..1) lowers the damping: 1 gives an undamped
    spring, 0 a heavily damped one. PyBullet's implicit contact spring also
    loses energy at a 1 ms step, so the measured restitution is below the
    nominal elasticity (bench/physics_contact.py prints both).
    """
    e = obj.elasticity
    if obj.kind == "membrane":
        return ContactParameters(stiffness=6000.0, damping=6.0 * (1.0 - e))
    if obj.kind in ("cymbal", "hihat", "bell"):
        return ContactParameters(stiffness=15000.0, damping=6.0 * (1.0 - e))
    return ContactParameters(stiffness=30000.0, damping=60.0 * (1.0 - e) + 5.0, friction=0.9)


HIHAT_GAP_RESOLUTION_M = 1e-5
"""The hi-hat rod's motor target is re-sent when the pedal moved the gap by more than this, metres."""
HIHAT_CONTACT_GAP_M = 0.002
"""PyBullet reports the hi-hat's plates touching (pushing each other apart) from about this gap, metres
(their collision margins, measured)."""
HIHAT_CHICK_RATE_M_S = 0.02
"""The hi-hat's clutch target closing faster than this (m/s) is the foot closing the pedal: the plates meeting
then are a pedal chick; otherwise (a stick knocking the top plate onto the bottom) they rattle."""
HIHAT_PULL_M = 0.004
"""The hi-hat's plates close their last this many metres above first touch at the pace of the footboard's toe (a
direct pull): about as fast as the toe, 1.5 times the ball of the foot (``hihat_gap``)."""
HIHAT_ROD_FORCE_N = 4000.0
"""Force limit of the hi-hat rod's position motor (the rod is rigid on a real stand), newtons: the 0.77 kg top plate
follows the pull's speed step at ``HIHAT_PULL_M`` (at 400 N, 520 m/s^2, loud chicks met no faster than medium ones:
velocities 0.5, 0.7, 0.85, 1.0 at 1.78, 1.82, 1.86, 1.50 m/s; at 4000 N 1.24, 1.80, 2.06, 2.28)."""
HIHAT_CLAMP_M = HIHAT_CONTACT_GAP_M - HIHAT_CLOSED_GAP_M
"""A pedal pressed to the end clamps the plates this much past first touch, metres (a closed hi-hat: the kit
model's ``HIHAT_CLOSED_GAP_M`` apart, where the planner aims the sticks)."""


def hihat_gap(press: float, opening: float, closes_at: float) -> float:
    """The hi-hat clutch's gap target (metres) for its pedal pressed ``press`` (0 rest ... 1 flat).

    The plates meet at ``closes_at`` of the travel (the kit's clutch setting), where the foot still moves: the
    pedal chick. Their last ``HIHAT_PULL_M`` close as a direct pull does on a real stand, the rod (and the top
    plate clutched on it) moving as far as the footboard's toe: the top meets the bottom plate about as fast as the
    toe moves, 1.5 times the ball of the foot (0.8-2.7 m/s for chicks at velocity 0.1-1). Above that the gap opens
    linearly with the pedal to ``opening`` x ``HIHAT_MAX_GAP_M`` at rest, so a pedal lifted for an open note leaves
    the gap it did (10.3 -> 10.9 mm at the planner's 7 cm lift). Pressed further, the plates are clamped together,
    up to ``HIHAT_CLAMP_M``. (Until 8 Dec the gap closed linearly over the whole travel: the plates met at a
    quarter of the ball's speed, 0.14-0.40 m/s, every chick below every stick stroke. Closing at the toe's pace
    over the whole rest opening, the top stood 15 mm up at an open note, and the stick touched it 50 ms early.
    Before 2 Dec they met only in the last 3 % of the travel, where the foot stops on the end stop, at 0.05-0.13
    m/s: one pedal note in three had no contact at all.)
    """
    if press >= closes_at:
        return HIHAT_CONTACT_GAP_M - HIHAT_CLAMP_M * min(1.0, (press - closes_at) / (1.0 - closes_at))
    rest = HIHAT_MAX_GAP_M * opening
    meet = math.sin(PEDAL_REST_ANGLE * (1.0 - closes_at))
    pulled = FOOTBOARD_LENGTH_M * (math.sin(PEDAL_REST_ANGLE * (1.0 - press)) - meet)  # the toe over its meeting
    direct = min(HIHAT_PULL_M, rest)
    if pulled <= direct:
        return HIHAT_CONTACT_GAP_M + pulled
    # the knee: where the toe has risen ``direct`` over its meeting height, and the gap from there to the rest's
    knee = 1.0 - math.asin(min(meet + direct / FOOTBOARD_LENGTH_M, 1.0)) / PEDAL_REST_ANGLE
    if knee <= 0.0:
        return HIHAT_CONTACT_GAP_M + min(pulled, rest)
    return HIHAT_CONTACT_GAP_M + direct + (rest - direct) * max(knee - press, 0.0) / knee


SLOW_SPRING_PERIOD_S = 0.004
"""The cymbals' springs are recomputed this often, seconds (they swing at about 1.2 Hz)."""
SPRING_TORQUE_FLOOR_NM = 1e-6
"""A slow spring (a cymbal's) whose torques are all below this (N m) is at rest: nothing is sent (PyBullet's
torques are zero after every step anyway), which saves a call per resting cymbal and step."""


@dataclass
class Spring:
    """An explicit spring-damper on one joint: tau = -k (q - rest) - c q_dot (N m/rad, N m s/rad)."""

    body: int
    joint: int
    stiffness: float
    damping: float
    rest: float = 0.0
    fast: bool = False
    """Updated at every physics step (a pedal's return spring under the foot); slow springs (cymbals swinging
    at about 1 Hz) may keep their torque between control updates."""


@dataclass
class Pedal:
    """A footboard (and optionally beaters geared to it)."""

    object_id: str
    body: int
    footboard_joint: int
    footboard_link: int
    beater_links: list[int] = field(default_factory=list)
    beater_parts: list[str] = field(default_factory=list)

    def press(self, world: World) -> float:
        """How far the footboard is pressed, 0 (rest) ... 1 (flat)."""
        return self.press_at(world.client.getJointState(self.body, self.footboard_joint)[0])

    @staticmethod
    def press_at(angle_rad: float) -> float:
        """How far a footboard at ``angle_rad`` is pressed, 0 (rest) ... 1 (flat)."""
        return min(max((PEDAL_REST_ANGLE - angle_rad) / PEDAL_REST_ANGLE, 0.0), 1.0)


@dataclass
class HiHat:
    bottom_body: int
    top_body: int
    rod_joint: int
    rest_opening: float
    closes_at: float
    """Fraction of the pedal's travel at which the plates meet (the kit's clutch setting)."""
    pedal: Pedal | None = None


@dataclass
class CymbalHinges:
    """Every cymbal's pivot and rest frame, and how its spring hinge is turned now (what a drummer aiming at a
    swinging cymbal sees; :func:`kernels.swing_displacement`)."""

    centre: np.ndarray
    """(C, 3) pivots, world metres (the plate's top centre)."""
    rotation: np.ndarray
    """(C, 3, 3) rest frames in the world (z: the plate's normal)."""
    radius: np.ndarray
    """(C,) plate radii, metres."""
    joints: list[tuple[int, int, int]]
    """(body, x joint, y joint) of each cymbal's hinge."""
    angles: np.ndarray
    """(C, 2) hinge angles (rad) as the springs last read them."""
    swinging: bool = False
    """Whether any of ``angles`` is non-zero (judged when they are read, not at every use)."""


@dataclass
class KitBodies:
    """Bodies of a kit in one world, and what contact extraction needs to know about them."""

    kit: Kit
    instrument_of: dict[tuple[int, int], str] = field(default_factory=dict)
    """(body, link) -> kit object id, for every collidable instrument link."""
    frame_of: dict[str, tuple[int, int]] = field(default_factory=dict)
    """kit object id -> (body, link) whose frame is the instrument frame."""
    strikers: dict[tuple[int, int], str] = field(default_factory=dict)
    """(body, link) -> striker part name for kit parts that strike (beaters, hi-hat top)."""
    springs: list[Spring] = field(default_factory=list)
    pedals: dict[str, Pedal] = field(default_factory=dict)
    hihat: HiHat | None = None
    pose_links: list[tuple[str, int, int]] = field(default_factory=list)
    """(name, body, link) of every kit link the graphics rate publishes."""
    _spring_groups: list[tuple[int, bool, list[int], list[int], list[int], list[float], list[float], list[float]]] \
        | None = None
    """(body, fast, spring joints, joints read, their places in the reading, stiffness, damping, rest)."""
    readings: dict[int, tuple[int, list[int], list[float]]] = field(default_factory=dict)
    """body -> (world step, joints, velocities rad/s or m/s) of the bodies :meth:`pre_step` read for that step
    (the contact tracker takes the kit's velocities from here rather than reading them again)."""
    cymbal_hinges: CymbalHinges | None = None
    _joint_angles: dict[tuple[int, int], float] = field(default_factory=dict)
    """(body, joint) -> angle (rad) of the spring joints at their last reading."""
    _spring_torques: list[list[float]] = field(default_factory=list)
    _spring_sends: list[bool] = field(default_factory=list)
    """Per group: whether its torques are sent (a resting cymbal's are not: below SPRING_TORQUE_FLOOR_NM)."""
    _slow_period_steps: int = 1
    _hihat_gap: float = -1.0
    _hihat_target: float = -1.0
    hihat_closing_rate: float = 0.0
    """How fast the pedal closes the hi-hat's clutch target this step, m/s (negative: opening)."""
    held_press: float = 0.0
    """A kit without the hi-hat's pedal body (the strike scene): how far a foot holds that pedal down (0 rest ...
    1 flat), the hi-hat's gap following as if the pedal were there."""

    def pedal_closing(self) -> bool:
        """Whether the foot is closing the hi-hat now (a plate contact is a chick, not a rattle)."""
        return self.hihat_closing_rate > HIHAT_CHICK_RATE_M_S

    def pre_step(self, world: World) -> None:
        """Apply the spring torques and the hi-hat rod coupling for the next step.

        The fast springs (pedals) are computed at every step; the slow ones (cymbals, swinging at about 1 Hz)
        every ``SLOW_SPRING_PERIOD_S``, their torques re-applied in between (PyBullet clears applied torques
        after every step).
        """
        c = world.client
        if self._spring_groups is None:
            groups: dict[tuple[int, bool], list[Spring]] = {}
            for s in self.springs:
                groups.setdefault((s.body, s.fast), []).append(s)
            self._spring_groups = []
            for (body, fast), group in groups.items():
                # read every moving joint of the body (a pedal's beater too): the contact tracker reuses it
                read = [j for j in range(c.getNumJoints(body)) if c.getJointInfo(body, j)[2] != p.JOINT_FIXED]
                self._spring_groups.append((body, fast, [s.joint for s in group], read,
                                            [read.index(s.joint) for s in group], [s.stiffness for s in group],
                                            [s.damping for s in group], [s.rest for s in group]))
            self._spring_torques = [[] for _ in self._spring_groups]
            self._spring_sends = [True for _ in self._spring_groups]
            self._slow_period_steps = max(1, round(SLOW_SPRING_PERIOD_S / world.dt))
        update = world.steps % self._slow_period_steps == 0
        angles = self._joint_angles
        for g, (body, fast, joints, read, at, k, d, rest) in enumerate(self._spring_groups):
            if update or fast or not self._spring_torques[g]:
                states = c.getJointStates(body, read)
                self.readings[body] = (world.steps, read, [s[1] for s in states])
                torques = []
                for joint, i, k_i, d_i, r_i in zip(joints, at, k, d, rest, strict=True):
                    q, qd = states[i][0], states[i][1]
                    angles[(body, joint)] = q
                    torques.append(-k_i * (q - r_i) - d_i * qd)
                self._spring_torques[g] = torques
                self._spring_sends[g] = fast or any(abs(t) > SPRING_TORQUE_FLOOR_NM for t in torques)
            if self._spring_sends[g]:
                c.setJointMotorControlArray(body, joints, p.TORQUE_CONTROL, forces=self._spring_torques[g])
        hinges = self.cymbal_hinges
        if update and hinges is not None:
            for cymbal, (hinge_body, x_joint, y_joint) in enumerate(hinges.joints):
                hinges.angles[cymbal, 0] = angles.get((hinge_body, x_joint), 0.0)
                hinges.angles[cymbal, 1] = angles.get((hinge_body, y_joint), 0.0)
            hinges.swinging = bool(hinges.angles.any())
        self._hihat_coupling(world)

    def _hihat_coupling(self, world: World) -> None:
        """The hi-hat's top follows its pedal: the rod's motor target is the gap the pedal leaves."""
        c = world.client
        hh = self.hihat
        if hh is not None:
            press = self.held_press
            if hh.pedal is not None:  # its angle as the pedal's return spring just read it
                q = self._joint_angles.get((hh.pedal.body, hh.pedal.footboard_joint))
                press = hh.pedal.press(world) if q is None else hh.pedal.press_at(q)
            gap = hihat_gap(press, hh.rest_opening, hh.closes_at)
            if self._hihat_target >= 0.0:
                self.hihat_closing_rate = (self._hihat_target - gap) / world.dt
            self._hihat_target = gap
            if abs(gap - self._hihat_gap) > HIHAT_GAP_RESOLUTION_M:  # a motor keeps its target: send changes
                self._hihat_gap = gap
                c.setJointMotorControl2(
                    hh.top_body, hh.rod_joint, p.POSITION_CONTROL, targetPosition=gap, force=HIHAT_ROD_FORCE_N,
                    positionGain=1.0
                )

    def hihat_opening(self, world: World) -> float:
        """How open the hi-hat is now: the simulated gap between its plates above first touch
        (``HIHAT_CONTACT_GAP_M``) over ``HIHAT_MAX_GAP_M``, 0 (touching or clamped) ... 1; the kit's ``opening`` at
        rest. (Before: the gap from zero over the maximum, which read a closed hi-hat as 0.06 open.)"""
        if self.hihat is None:
            return 0.0
        q = world.client.getJointState(self.hihat.top_body, self.hihat.rod_joint)[0]
        return float(np.clip((q - HIHAT_CONTACT_GAP_M) / HIHAT_MAX_GAP_M, 0.0, 1.0))


def _set_contact(world: World, body: int, link: int, obj: KitObject) -> None:
    cp = contact_parameters(obj)
    world.client.changeDynamics(
        body, link, contactStiffness=cp.stiffness, contactDamping=cp.damping, lateralFriction=cp.friction,
        restitution=0.0,
    )


def _free_joints(world: World, body: int) -> None:
    """Switch off PyBullet's default velocity motors so joints move freely (springs are explicit)."""
    for j in range(world.client.getNumJoints(body)):
        world.client.setJointMotorControl2(body, j, p.VELOCITY_CONTROL, force=0.0)


def _membrane(world: World, kb: KitBodies, obj: KitObject) -> None:
    depth = max(obj.depth, 0.02)
    rgba = _DARK if obj.kind == "bell" else _HEAD
    robot = Robot(obj.id)
    robot.add_link(Link(obj.id, Inertial(0.0), (Shape("cylinder", (obj.radius, depth, 0.0), xyz=(0, 0, -depth / 2),
                                                      rgba=rgba),)))
    body = load_robot(world.client, robot, obj.position, quat_from_rpy_deg(obj.rotation_deg), fixed_base=True)
    _set_contact(world, body, -1, obj)
    kb.instrument_of[(body, -1)] = obj.id
    kb.frame_of[obj.id] = (body, -1)
    kb.pose_links.append((f"kit.{obj.id}", body, -1))


def _cymbals(world: World, kb: KitBodies, objects: list[KitObject]) -> None:
    """Every cymbal in one fixed-base body: per cymbal a mount fixed where the kit puts it, and the cymbal on a
    two-axis spring hinge. One body rather than one per cymbal: the springs are read and their torques sent in
    one call each per step (they are independent branches of one tree, so they swing as separate bodies would).
    """
    if not objects:
        return
    robot = Robot("cymbals")
    robot.add_link(Link("cymbal_stands", Inertial(0.0)))
    swing = 0.6
    for obj in objects:
        mass = math.pi * obj.radius**2 * obj.thickness * CYMBAL_DENSITY
        inertia = cylinder_inertia(mass, obj.radius, obj.thickness)
        shapes = [Shape("cylinder", (obj.radius, obj.thickness, 0.0), xyz=(0, 0, -obj.thickness / 2), rgba=_BRASS)]
        if obj.bell_radius > 0:
            bell_h = obj.bell_height + obj.thickness  # the bell's cylinder starts at the plate's underside
            shapes.append(Shape("cylinder", (obj.bell_radius, bell_h, 0.0), xyz=(0, 0, bell_h / 2 - obj.thickness),
                                rgba=_BRASS))
        mount, hinge = f"{obj.id}_mount", f"{obj.id}_hinge_x"
        robot.add_link(Link(mount, Inertial(0.0)))
        robot.add_link(Link(hinge, Inertial(1e-3, inertia=(1e-7, 1e-7, 1e-7, 0, 0, 0))))
        robot.add_link(Link(obj.id, Inertial(mass, inertia=inertia), tuple(shapes)))
        roll, pitch, yaw = (math.radians(a) for a in obj.rotation_deg)
        robot.add_joint(Joint(f"{obj.id}_stand", "fixed", "cymbal_stands", mount, xyz=obj.position,
                              rpy=(roll, pitch, yaw)))
        robot.add_joint(Joint(f"{obj.id}_swing_x", "revolute", mount, hinge, axis=(1, 0, 0), lower=-swing,
                              upper=swing, effort=100, velocity=50))
        robot.add_joint(Joint(f"{obj.id}_swing_y", "revolute", hinge, obj.id, axis=(0, 1, 0), lower=-swing,
                              upper=swing, effort=100, velocity=50))
    body = load_robot(world.client, robot, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0), fixed_base=True,
                      flags=p.URDF_USE_INERTIA_FROM_FILE)
    _free_joints(world, body)
    names = {world.client.getJointInfo(body, j)[12].decode(): j for j in range(world.client.getNumJoints(body))}
    frames = [world.link_frame(body, names[obj.id]) for obj in objects]  # at rest: the hinges at zero
    kb.cymbal_hinges = CymbalHinges(
        centre=np.array([pos for pos, _ in frames], dtype=float),
        rotation=np.array([rotation_matrix(quat) for _, quat in frames]),
        radius=np.array([obj.radius for obj in objects]),
        joints=[(body, names[f"{obj.id}_hinge_x"], names[obj.id]) for obj in objects],
        angles=np.zeros((len(objects), 2)),
    )
    for obj in objects:
        link = names[obj.id]
        # swing at about 1.2 Hz, amplitude decaying with a 1.5 s time constant
        i_diam = cylinder_inertia(math.pi * obj.radius**2 * obj.thickness * CYMBAL_DENSITY, obj.radius,
                                  obj.thickness)[0]
        k = i_diam * (2 * math.pi * 1.2) ** 2
        c = 2 * i_diam / 1.5
        kb.springs += [Spring(body, names[f"{obj.id}_hinge_x"], k, c), Spring(body, link, k, c)]
        _set_contact(world, body, link, obj)
        kb.instrument_of[(body, link)] = obj.id
        kb.frame_of[obj.id] = (body, link)
        kb.pose_links.append((f"kit.{obj.id}", body, link))


def _footboard_robot(robot: Robot, prefix: str, parent: str, xyz: tuple[float, float, float]) -> str:
    """Add a footboard hinged at its heel (at ``xyz`` in ``parent``) rising along +y; returns its link name."""
    name = f"{prefix}footboard"
    m = 0.4
    robot.add_link(Link(name, Inertial(m, com=(0, FOOTBOARD_LENGTH_M / 2, 0.008),
                                       inertia=(m * FOOTBOARD_LENGTH_M**2 / 12, 1e-4, m * FOOTBOARD_LENGTH_M**2 / 12,
                                                0, 0, 0)),
                        (Shape("box", (0.09, FOOTBOARD_LENGTH_M, 0.012), xyz=(0, FOOTBOARD_LENGTH_M / 2, 0.006),
                               rgba=_SILVER),)))
    robot.add_joint(Joint(f"{prefix}heel", "revolute", parent, name, xyz=xyz, axis=(1, 0, 0), lower=0.0,
                          upper=PEDAL_REST_ANGLE + 0.05, effort=200, velocity=50))
    return name


def _pedal_robot(obj: KitObject, beater: Beater | None) -> Robot:
    """A pedal body: base plate, footboard and, for a bass-drum pedal, its ``beater`` (``common.kit.kit_hardware``:
    the numbers the live view and the glTF export draw) geared to it."""
    robot = Robot(obj.id)
    robot.add_link(Link("plate", Inertial(0.0), (Shape("box", (0.10, 0.32, 0.01), xyz=(0, 0, -0.015),
                                                       rgba=_DARK),)))
    _footboard_robot(robot, "", "plate", (0.0, -FOOTBOARD_LENGTH_M / 2, 0.0))
    if beater is not None:
        rod = beater.rod_length
        m_head, m_rod = 0.05, 0.03
        inertial = Inertial(m_head + m_rod, com=(0, 0, rod * 0.8), inertia=(2e-4, 2e-4, 1e-5, 0, 0, 0))
        robot.add_link(Link("beater", inertial,
                            (Shape("cylinder", (beater.rod_radius, rod, 0.0), xyz=(0, 0, rod / 2), rgba=_SILVER,
                                   collision=False),
                             Shape("sphere", (beater.ball_radius, 0, 0), xyz=(0, 0, rod), rgba=_HEAD))))
        # q = 0: the rod points from the axle to the ball pressed into the head; positive q tilts it back toward the
        # drummer
        robot.add_joint(Joint("beater_axle", "revolute", "plate", "beater", xyz=beater.axle_from_pedal,
                              rpy=(-beater.lean_rad, 0, 0), axis=(1, 0, 0), lower=-0.02, upper=1.6, effort=200,
                              velocity=80))
    return robot


def _pedal(world: World, kb: KitBodies, obj: KitObject) -> None:
    kit = kb.kit
    beater = next((b for b in kit_hardware(kit).beaters if b.pedal == obj.id), None)
    part = "" if beater is None else "kick_beater" if obj.id == kit.kick_pedal() else "kick_beater_left"
    robot = _pedal_robot(obj, beater)
    body = load_robot(world.client, robot, obj.position, (0.0, 0.0, 0.0, 1.0), fixed_base=True,
                      flags=p.URDF_USE_INERTIA_FROM_FILE)
    _free_joints(world, body)
    names = {world.client.getJointInfo(body, j)[12].decode(): j for j in range(world.client.getNumJoints(body))}
    foot = names["footboard"]
    world.client.resetJointState(body, foot, PEDAL_REST_ANGLE)
    pedal = Pedal(obj.id, body, foot, foot)
    kb.springs.append(Spring(body, foot, stiffness=PEDAL_SPRING_NM_PER_RAD, damping=0.3, rest=PEDAL_REST_ANGLE,
                             fast=True))
    _set_contact(world, body, foot, obj)
    kb.pose_links.append((f"kit.{obj.id}.footboard", body, foot))
    if "beater" in names:
        # gear: pressing the footboard (angle down) swings the beater forward (angle down) ratio times as far
        link = names["beater"]
        world.client.resetJointState(body, link, BEATER_REST_RAD)
        cid = world.client.createConstraint(body, foot, body, link, p.JOINT_GEAR, [1, 0, 0], [0, 0, 0], [0, 0, 0])
        world.client.changeConstraint(cid, gearRatio=-PEDAL_REST_ANGLE / BEATER_REST_RAD, maxForce=500.0, erp=0.2)
        pedal.beater_links.append(link)
        pedal.beater_parts.append(part)
        kb.strikers[(body, link)] = part
        kb.pose_links.append((f"kit.{obj.id}.beater", body, link))
    kb.pedals[obj.id] = pedal


def _hihat(world: World, kb: KitBodies, obj: KitObject) -> None:
    quat = quat_from_rpy_deg(obj.rotation_deg)
    mass = math.pi * obj.radius**2 * obj.thickness * CYMBAL_DENSITY
    plate = Shape("cylinder", (obj.radius, obj.thickness, 0.0), xyz=(0, 0, -obj.thickness / 2), rgba=_BRASS)
    bottom = Robot(f"{obj.id}_bottom")
    bottom.add_link(Link(obj.id, Inertial(0.0), (plate,)))
    b_body = load_robot(world.client, bottom, obj.position, quat, fixed_base=True)
    _set_contact(world, b_body, -1, obj)
    top = Robot(f"{obj.id}_top")
    top.add_link(Link("rod", Inertial(0.0), (Shape("cylinder", (0.004, 0.6, 0.0), xyz=(0, 0, -0.3), rgba=_SILVER,
                                                   collision=False),)))
    top_shape = Shape("cylinder", (obj.radius, obj.thickness, 0.0), xyz=(0, 0, obj.thickness / 2), rgba=_BRASS)
    top.add_link(Link("top", Inertial(mass, inertia=cylinder_inertia(mass, obj.radius, obj.thickness)), (top_shape,)))
    top.add_joint(Joint("clutch", "prismatic", "rod", "top", axis=(0, 0, 1), lower=0.0, upper=HIHAT_MAX_GAP_M,
                        effort=400, velocity=5))
    t_body = load_robot(world.client, top, obj.position, quat, fixed_base=True, flags=p.URDF_USE_INERTIA_FROM_FILE)
    world.client.resetJointState(t_body, 0, hihat_gap(0.0, obj.opening, obj.closes_at))
    _set_contact(world, t_body, 0, obj)
    kb.instrument_of[(b_body, -1)] = obj.id
    kb.instrument_of[(t_body, 0)] = obj.id
    kb.strikers[(t_body, 0)] = "hihat_top"
    kb.frame_of[obj.id] = (b_body, -1)
    kb.hihat = HiHat(b_body, t_body, 0, obj.opening, obj.closes_at)
    kb.pose_links.append((f"kit.{obj.id}.bottom", b_body, -1))
    kb.pose_links.append((f"kit.{obj.id}.top", t_body, 0))


def _throne(world: World, kb: KitBodies, obj: KitObject) -> None:
    robot = Robot(obj.id)
    seat_h = 0.09
    robot.add_link(Link(obj.id, Inertial(0.0), (
        Shape("cylinder", (obj.radius, seat_h, 0.0), xyz=(0, 0, -seat_h / 2), rgba=_DARK),
        Shape("cylinder", (0.02, obj.position[2] - seat_h, 0.0), xyz=(0, 0, -(obj.position[2] + seat_h) / 2),
              rgba=_SILVER, collision=False),
    )))
    body = load_robot(world.client, robot, obj.position, (0.0, 0.0, 0.0, 1.0), fixed_base=True)
    _set_contact(world, body, -1, obj)
    kb.frame_of[obj.id] = (body, -1)
    kb.pose_links.append((f"kit.{obj.id}", body, -1))


def _stands(world: World, kb: KitBodies, objects: list[KitObject], kick: str | None) -> None:
    """One static, visual-only body holding a rod under every mounted drum and cymbal (none under the kick, ``kick``
    its id)."""
    shapes = [Shape("cylinder", (STAND_ROD_RADIUS_M, height, 0.0), xyz=(float(top[0]), float(top[1]), height / 2),
                    rgba=_SILVER, collision=False) for top, height in stand_rods(objects, kick)]
    if not shapes:
        return
    robot = Robot("stands")
    robot.add_link(Link("stands", Inertial(0.0), tuple(shapes)))
    body = load_robot(world.client, robot, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0), fixed_base=True)
    kb.pose_links.append(("kit.stands", body, -1))


def build_kit(world: World, kit: Kit, only: set[str] | None = None) -> KitBodies:
    """Create the bodies of ``kit`` in ``world``; ``only``: restrict to these object ids."""
    kb = KitBodies(kit=kit)
    objects = [o for o in kit.objects if only is None or o.id in only]
    for obj in objects:
        if obj.kind in ("membrane", "bell"):
            _membrane(world, kb, obj)
        elif obj.kind == "hihat":
            _hihat(world, kb, obj)
        elif obj.kind == "pedal":
            _pedal(world, kb, obj)
        elif obj.kind == "throne":
            _throne(world, kb, obj)
    _cymbals(world, kb, [obj for obj in objects if obj.kind == "cymbal"])
    hihat_pedal = kit.hihat_pedal()  # HIHATPEDAL's footboard, whatever its id
    if kb.hihat is not None and hihat_pedal in kb.pedals:
        kb.hihat.pedal = kb.pedals[hihat_pedal]
    if only is None:
        kick = kit.kick()
        _stands(world, kb, objects, None if kick is None else kick.id)
    return kb


def instrument_frame(world: World, kb: KitBodies, object_id: str) -> tuple[np.ndarray, np.ndarray]:
    """World position (3,) and rotation matrix (3, 3) of an instrument's frame now."""
    body, link = kb.frame_of[object_id]
    pos, quat = world.link_frame(body, link)
    return pos, rotation_matrix(quat)
