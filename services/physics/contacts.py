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

from dataclasses import dataclass

import numpy as np

from common.messages import Contact
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


@dataclass
class _Episode:
    first_step: int
    approach_velocity: float


class ContactTracker:
    """Turns PyBullet contact points into Contact messages, one per pair and step."""

    def __init__(self, world: World, kit: KitBodies) -> None:
        self.world = world
        self.kit = kit
        self.strikers: dict[Key, Striker] = {}
        for (body, link), part in kit.strikers.items():
            self.strikers[(body, link)] = Striker(body, link, part)
        self._moving_instruments: list[Key] = [
            key for key in kit.instrument_of if world.client.getDynamicsInfo(key[0], key[1])[0] > 0
        ]
        self._velocities: dict[Key, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        self._episodes: dict[tuple[Key, str], _Episode] = {}
        self._groups: list[tuple[int, list[int]]] | None = None
        self._instrument_groups: list[tuple[int, list[int]]] = []
        self.instrument_every = 1
        """Read the moving instruments' (cymbals') velocities every this many steps; strikers every step. A
        cymbal swings at about 1 Hz: a few milliseconds old, its velocity is still its velocity."""
        self._calls = 0
        self.touching: set[str] = set()
        """Base part names of the strikers in contact at the last step (e.g. left_stick, kick_beater)."""
        self.episodes_started = 0

    def add_striker(self, striker: Striker) -> None:
        self.strikers[(striker.body, striker.link)] = striker
        self._groups = None

    def before_step(self) -> None:
        """Record striker and moving-instrument velocities before the step (for approach velocities)."""
        vel = self._velocities
        if self._groups is None:
            self._groups = _by_body(list(self.strikers))
            self._instrument_groups = _by_body([k for k in self._moving_instruments if k not in self.strikers])
        groups = self._groups
        if self._calls % self.instrument_every == 0:
            groups = groups + self._instrument_groups
        self._calls += 1
        c = self.world.client
        for body, links in groups:
            real = [k for k in links if k >= 0]
            if real:
                states = c.getLinkStates(body, real, computeLinkVelocity=1, computeForwardKinematics=1)
                for k, s in zip(real, states, strict=True):
                    vel[(body, k)] = (np.asarray(s[0]), np.asarray(s[6]), np.asarray(s[7]))
            if -1 in links:
                vel[(body, -1)] = self.world.link_velocity(body, -1)

    def _point_velocity(self, key: Key, point: np.ndarray) -> np.ndarray:
        rec = self._velocities.get(key)
        if rec is None:
            return np.zeros(3)
        com, lin, ang = rec
        return lin + np.cross(ang, point - com)

    def after_step(self, time: float, step: int) -> list[Contact]:
        """Contacts of the step just taken; ``time``: rig time of the step, seconds."""
        c = self.world.client
        groups: dict[tuple[Key, str], list[tuple[np.ndarray, np.ndarray, float, Key]]] = {}
        for body in sorted({k[0] for k in self.strikers}):
            for cp in c.getContactPoints(bodyA=body):
                key = (cp[1], cp[3])
                if key not in self.strikers:
                    continue
                inst_key = (cp[2], cp[4])
                instrument = self.kit.instrument_of.get(inst_key)
                if instrument is None or inst_key == key:
                    continue
                force = float(cp[9])
                if force <= 0.0:
                    continue  # within the collision margin, or separating: no push this step
                groups.setdefault((key, instrument), []).append(
                    (np.asarray(cp[6], dtype=float), np.asarray(cp[7], dtype=float), force, inst_key)
                )
        out: list[Contact] = []
        dt = self.world.dt
        for pair in sorted(groups):
            key, instrument = pair
            points = groups[pair]
            forces = np.array([f for _, _, f, _ in points])
            total = float(forces.sum())
            weights = forces / total if total > 0 else np.full(len(points), 1.0 / len(points))
            pos = sum(w * pt for w, (pt, _, _, _) in zip(weights, points, strict=True))
            normal = sum(w * n for w, (_, n, _, _) in zip(weights, points, strict=True))
            assert isinstance(pos, np.ndarray) and isinstance(normal, np.ndarray)
            norm = float(np.linalg.norm(normal))
            normal = normal / norm if norm > 0 else np.asarray(points[0][1])
            episode = self._episodes.get(pair)
            if episode is None:
                v_rel = self._point_velocity(key, pos) - self._point_velocity(points[0][3], pos)
                episode = _Episode(first_step=step, approach_velocity=float(-v_rel @ normal))
                self._episodes[pair] = episode
                self.episodes_started += 1
            origin, rot = instrument_frame(self.world, self.kit, instrument)
            local = rot.T @ (pos - origin)
            out.append(
                Contact(
                    time=time,
                    step=step,
                    instrument=instrument,
                    part=self.strikers[key].part_at(self.world, pos),
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
                )
            )
        for pair in list(self._episodes):
            if pair not in groups:
                del self._episodes[pair]
        self.touching = {self.strikers[key].part for key, _ in groups}
        return out


def _by_body(keys: list[Key]) -> list[tuple[int, list[int]]]:
    """(body, link) keys grouped per body, sorted: one state read per body."""
    groups: dict[int, list[int]] = {}
    for body, link in keys:
        groups.setdefault(body, []).append(link)
    return sorted((body, sorted(set(links))) for body, links in groups.items())
