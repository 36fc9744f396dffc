"""Contacts between strikers (stick bead and shaft, beaters, hi-hat top) and instruments.

After every physics step, each (striker link, instrument) pair in contact
gives one :class:`~common.messages.Contact`: PyBullet's contact points of the
pair are merged (force-weighted position and normal, summed force). The
relative normal velocity is measured *before* the step that first touched
(the solver has already changed it after), and is carried in every message of
the same contact episode, so a receiver that misses the first datagram still
gets the incoming velocity.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from common.messages import Contact
from common.quiet_pybullet import pybullet as p
from services.physics.kitbodies import KitBodies, instrument_frame
from services.physics.sticks import StickSpec
from services.physics.world import World, rotation_matrix

Key = tuple[int, int]


@dataclass(frozen=True)
class Striker:
    """A link that strikes: a fixed part name, or a stick (part from where it touched)."""

    body: int
    link: int
    part: str
    stick: StickSpec | None = None
    side: str = ""

    def part_at(self, world: World, point: np.ndarray) -> str:
        if self.stick is None:
            return self.part
        pos, quat = world.link_frame(self.body, self.link)
        tip = pos + rotation_matrix(quat) @ np.array([0.0, self.stick.tip_offset, 0.0])
        return self.stick.part(self.side, float(np.linalg.norm(point - tip)))


PLATE_CONTACT_S = 0.01
"""The hi-hat's plates report a contact for this long, seconds; then they rest clamped together (the foot holds the
pedal) and send nothing until they part: a chick's sound and figures are in its first milliseconds, and the
resting contact was 70 % of all messages of a render (1,000 a second whenever the hi-hat was closed)."""
HIHAT_TOP = "hihat_top"
HIHAT_RATTLE = "hihat_rattle"
"""The hi-hat's plates meeting while the foot is not closing the pedal (a stick knocked the top onto the bottom):
reported as this part instead of ``hihat_top`` (a pedal chick), so interaction can tell them apart."""


@dataclass
class _Episode:
    first_step: int
    approach_velocity: float
    part: str | None = None
    """A striker whose part the episode's start decides (the hi-hat top: chick or rattle)."""
    openness: float = -1.0
    """A contact on the hi-hat: how open its plates were at the episode's first step (KitBodies.hihat_opening);
    -1 for other instruments."""


@dataclass(frozen=True)
class _ChainJoint:
    joint: int
    prismatic: bool
    axis_local: np.ndarray


class ContactTracker:
    """Turns PyBullet contact points into Contact messages, one per pair and step.

    Approach velocities come from joint velocities: before every step the tracker keeps the joint
    velocities of every body with a striker or a moving instrument (the scene hands over those it has
    read anyway, :meth:`provide_joint_velocities`; the tracker reads the kit's small bodies itself), and
    only when a contact starts does it turn them into the velocity of the contact point through the
    chain of joints above the link (``sum axis_j x (p - o_j) qd_j``). Reading the strikers' link
    velocities at every step cost more than the rest of the bookkeeping together.
    """

    def __init__(self, world: World, kit: KitBodies) -> None:
        self.world = world
        self.kit = kit
        self.strikers: dict[Key, Striker] = {}
        for (body, link), part in kit.strikers.items():
            self.strikers[(body, link)] = Striker(body, link, part)
        self._moving_instruments: list[Key] = [
            key for key in kit.instrument_of if world.client.getDynamicsInfo(key[0], key[1])[0] > 0
        ]
        self._episodes: dict[tuple[Key, str], _Episode] = {}
        self._read_bodies: tuple[list[tuple[int, list[int]]], list[tuple[int, list[int]]]] | None = None
        self._provided: set[int] = set()
        self._qd: dict[int, tuple[dict[int, int], Sequence[float] | np.ndarray, Sequence[int]]] = {}
        """body -> ({joint: index}, velocities before the step (rad/s or m/s) by index, the joints read)."""
        self._index_maps: dict[tuple[int, ...], dict[int, int]] = {}
        self._chains: dict[Key, list[_ChainJoint]] = {}
        self.instrument_every = 1
        """Read the moving instruments' (cymbals') joint velocities at steps that are multiples of this; strikers
        every step. A cymbal swings at about 1 Hz: a few milliseconds old, its velocity is still its velocity."""
        self.touching: set[str] = set()
        """Base part names of the strikers in contact at the last step (e.g. left_stick, kick_beater)."""
        self.touching_instruments: set[tuple[str, str]] = set()
        """(striker base part, instrument) pairs in contact at the last step."""
        self.episodes_started = 0
        self.last_points: tuple[tuple[Any, ...], ...] = ()
        """Every contact point of the last step, as PyBullet reads them (the drummer's feet on the pedals too)."""

    def add_striker(self, striker: Striker) -> None:
        self.strikers[(striker.body, striker.link)] = striker
        self._read_bodies = None

    def provide_joint_velocities(self, body: int, joints: list[int], velocities: np.ndarray) -> None:
        """The scene's reading of ``body``'s joint velocities at the start of this step (the tracker then does
        not read that body itself)."""
        if body not in self._provided:
            self._provided.add(body)
            self._read_bodies = None
        record = self._qd.get(body)
        index = record[0] if record is not None and record[2] is joints else self._index_map(joints)
        self._qd[body] = (index, velocities, joints)

    def _index_map(self, joints: Sequence[int]) -> dict[int, int]:
        key = tuple(joints)
        index = self._index_maps.get(key)
        if index is None:
            index = self._index_maps[key] = {j: k for k, j in enumerate(key)}
        return index

    def before_step(self) -> None:
        """Keep the joint velocities of the bodies that may touch (for approach velocities)."""
        if self._read_bodies is None:
            c = self.world.client
            striker_bodies = sorted({k[0] for k in self.strikers} - self._provided)
            instrument_bodies = sorted({k[0] for k in self._moving_instruments} - self._provided - set(striker_bodies))
            self._read_bodies = tuple(  # type: ignore[assignment]
                [(b, [j for j in range(c.getNumJoints(b)) if c.getJointInfo(b, j)[2] != p.JOINT_FIXED])
                 for b in bodies] for bodies in (striker_bodies, instrument_bodies))
        assert self._read_bodies is not None
        strikers, instruments = self._read_bodies
        step = self.world.steps
        bodies = strikers + instruments if step % self.instrument_every == 0 else strikers
        c = self.world.client
        for body, joints in bodies:
            reading = self.kit.readings.get(body)
            if reading is not None and reading[0] == step and reading[1] == joints:  # the kit's springs read it
                self._qd[body] = (self._index_map(joints), reading[2], joints)
            elif joints:
                self._qd[body] = (self._index_map(joints), [s[1] for s in c.getJointStates(body, joints)], joints)

    def _chain(self, key: Key) -> list[_ChainJoint]:
        """The moving joints from ``key``'s link up to its body's base."""
        chain = self._chains.get(key)
        if chain is None:
            c = self.world.client
            body, link = key
            chain = []
            while link >= 0:
                info = c.getJointInfo(body, link)
                if info[2] in (p.JOINT_REVOLUTE, p.JOINT_PRISMATIC):
                    chain.append(_ChainJoint(link, info[2] == p.JOINT_PRISMATIC, np.asarray(info[13], dtype=float)))
                link = info[16]
            self._chains[key] = chain
        return chain

    def _point_velocity(self, key: Key, point: np.ndarray) -> np.ndarray:
        """Velocity (3,) m/s before this step of the point ``point`` (world, metres) fixed to link ``key``."""
        body = key[0]
        record = self._qd.get(body)
        chain = self._chain(key)
        c = self.world.client
        base, _ = c.getBasePositionAndOrientation(body)
        lin, ang = c.getBaseVelocity(body)  # zero for a fixed base; a pinned floating base barely moves
        v = np.asarray(lin, dtype=float) + np.cross(np.asarray(ang, dtype=float), point - np.asarray(base))
        if record is None or not chain:
            return v
        index, qd, _ = record
        states = c.getLinkStates(body, [j.joint for j in chain], computeForwardKinematics=1)
        for joint, state in zip(chain, states, strict=True):
            k = index.get(joint.joint)
            rate = 0.0 if k is None else float(qd[k])
            if rate == 0.0:
                continue
            axis = rotation_matrix(state[5]) @ joint.axis_local
            v += rate * (axis if joint.prismatic else np.cross(axis, point - np.asarray(state[4])))
        return v

    def after_step(self, time: float, step: int) -> list[Contact]:
        """Contacts of the step just taken; ``time``: rig time of the step, seconds."""
        c = self.world.client
        # per pair: (point, normal as read, its sign, force, instrument key), made arrays only for the pairs reported
        groups: dict[tuple[Key, str], list[tuple[Any, Any, float, float, Key]]] = {}
        strikers, instrument_of = self.strikers, self.kit.instrument_of
        # one read of every contact point in the world (a call per striker body cost more); a pair is reported
        # once, in either order: take each point from the side of its striker (position on the instrument,
        # normal from the instrument to the striker)
        self.last_points = c.getContactPoints()
        for cp in self.last_points:
            force = float(cp[9])
            if force <= 0.0:
                continue  # within the collision margin, or separating: no push this step
            a, b = (cp[1], cp[3]), (cp[2], cp[4])
            if a == b or (a not in strikers and b not in strikers):
                continue  # most points: a foot on a pedal, the hi-hat's plates at rest
            for key, inst_key, point, sign in ((a, b, cp[6], 1.0), (b, a, cp[5], -1.0)):
                if key not in strikers:
                    continue
                instrument = instrument_of.get(inst_key)
                if instrument is None:
                    continue
                groups.setdefault((key, instrument), []).append((point, cp[7], sign, force, inst_key))
        out: list[Contact] = []
        dt = self.world.dt
        hihat = self.kit.hihat
        for pair in sorted(groups):
            key, instrument = pair
            episode = self._episodes.get(pair)
            if (episode is not None and self.strikers[key].part == HIHAT_TOP
                    and (step - episode.first_step) * dt >= PLATE_CONTACT_S):
                continue  # the plates resting together (before any arithmetic: most steps of a closed hi-hat)
            points = [(np.asarray(point, dtype=float), sign * np.asarray(normal, dtype=float), force, inst_key)
                      for point, normal, sign, force, inst_key in groups[pair]]
            forces = np.array([f for _, _, f, _ in points])
            total = float(forces.sum())
            weights = forces / total if total > 0 else np.full(len(points), 1.0 / len(points))
            pos = sum(w * pt for w, (pt, _, _, _) in zip(weights, points, strict=True))
            normal = sum(w * n for w, (_, n, _, _) in zip(weights, points, strict=True))
            assert isinstance(pos, np.ndarray) and isinstance(normal, np.ndarray)
            norm = float(np.linalg.norm(normal))
            normal = normal / norm if norm > 0 else np.asarray(points[0][1])
            if episode is None:
                v_rel = self._point_velocity(key, pos) - self._point_velocity(points[0][3], pos)
                episode = _Episode(first_step=step, approach_velocity=float(-v_rel @ normal))
                if self.strikers[key].part == HIHAT_TOP and not self.kit.pedal_closing():
                    episode.part = HIHAT_RATTLE
                if hihat is not None and points[0][3][0] in (hihat.bottom_body, hihat.top_body):
                    # the gap when the stick met the plates is what sounds: an open or a closed stroke
                    episode.openness = self.kit.hihat_opening(self.world)
                self._episodes[pair] = episode
                self.episodes_started += 1
            origin, rot = instrument_frame(self.world, self.kit, instrument)
            local = rot.T @ (pos - origin)
            out.append(
                Contact(
                    time=time,
                    step=step,
                    instrument=instrument,
                    part=episode.part or self.strikers[key].part_at(self.world, pos),
                    x=float(pos[0]),
                    y=float(pos[1]),
                    z=float(pos[2]),
                    local_x=float(local[0]),
                    local_y=float(local[1]),
                    local_z=float(local[2]),
                    normal_x=float(np.clip(normal[0], -1.0, 1.0)),
                    normal_y=float(np.clip(normal[1], -1.0, 1.0)),
                    normal_z=float(np.clip(normal[2], -1.0, 1.0)),
                    normal_velocity=episode.approach_velocity,
                    impulse=total * dt,
                    normal_force=total,
                    openness=episode.openness,
                )
            )
        for pair in list(self._episodes):
            if pair not in groups:
                del self._episodes[pair]
        self.touching_instruments = {(self.strikers[key].part, instrument) for key, instrument in groups}
        self.touching = {part for part, _ in self.touching_instruments}
        return out
