"""The pose editor's model (the 2001 paper's poser GUI) on physics' 57-DOF percussionist.

The editor's sliders are the body's 57 DOF (19 joints x intrinsic x-y-z angles,
:mod:`common.character`). :class:`CharacterPoser` does the forward kinematics
of that body from one of its poses, as physics publishes it (``/batteur/skeleton``
names, ``/batteur/pose`` link frames): the link offsets and the current joint
angles are read back from the frames (a child's frame is its parent's turned by
``Rx Ry Rz``), sticks stay in their hands, kit links stay where they are.
Without a live body (physics not running) the editor shows a snapshot of the
default drummer (``character.json``, built from physics by
``python -m tests.graphics.character_snapshot``), which also gives the joint
limits for the sliders and where the stick tips and balls of the feet are in
their links (the effectors saved with each key pose).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from common.character import AXES, BASE_LINKS, DOF_NAMES, HELD_LINKS, JOINT_LINKS, JOINTS, N_DOF
from common.gesture.keyposes import KeyPose

SNAPSHOT = Path(__file__).with_name("character.json")
LIMBS = ("left_hand", "right_hand", "left_foot", "right_foot")


@dataclass(frozen=True)
class CharacterInfo:
    """The default drummer as physics builds it (see the module docstring).

    Attributes
    ----------
    names : list of str
        Body link names, in /batteur/skeleton order.
    rest : np.ndarray, shape (L, 7)
        Rest pose: link frames, metres and quaternions (x y z w).
    lower, upper : np.ndarray, shape (57,)
        Joint limits (physics' Euler boxes), radians.
    effectors : dict
        limb -> (link name, offset (3,) metres in that link's frame) of the stick tip / ball of the foot.
    """

    names: list[str]
    rest: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    effectors: dict[str, tuple[str, np.ndarray]]


@lru_cache(maxsize=2)
def load_character(path: Path = SNAPSHOT) -> CharacterInfo:
    data = json.loads(path.read_text(encoding="utf-8"))
    limits = np.radians(np.asarray(data["limits_deg"], dtype=float))
    return CharacterInfo(
        names=list(data["names"]),
        rest=np.asarray(data["rest"], dtype=float),
        lower=limits[:, 0],
        upper=limits[:, 1],
        effectors={limb: (e["link"], np.asarray(e["offset"], dtype=float)) for limb, e in data["effectors"].items()},
    )


def is_character(names: Sequence[str]) -> bool:
    """Whether a skeleton has every link the 57 DOF move (physics' drummer)."""
    have = set(names)
    return all(child in have for _, child in JOINT_LINKS.values())


class CharacterPoser:
    """Forward kinematics of the 57-DOF body, set up from one pose of it (see the module docstring).

    Parameters
    ----------
    names : sequence of str
        Link names of the pose (physics' skeleton; kit and other links are kept still).
    pose : np.ndarray, shape (L, 7)
        Link frames, metres and quaternions (x y z w).
    info : CharacterInfo, optional
        Limits and effector offsets (default: the shipped snapshot).

    Raises ``ValueError`` when a link the joints move is missing.
    """

    def __init__(self, names: Sequence[str], pose: np.ndarray, info: CharacterInfo | None = None) -> None:
        self.info = info or load_character()
        self.names = list(names)
        self.reference = np.asarray(pose, dtype=float).reshape(len(self.names), 7).copy()
        index = {n: i for i, n in enumerate(self.names)}
        missing = [child for _, child in JOINT_LINKS.values() if child not in index]
        if missing:
            raise ValueError(f"not physics' 57-DOF body: no link {', '.join(missing[:4])}")
        self.index = index
        ref = self.reference
        rot = Rotation.from_quat(ref[:, 3:])
        self.rows: list[tuple[int, int]] = []  # (parent row or -1 for a base on the throne, child row) per joint
        self.offsets = np.zeros((len(JOINTS), 3))
        """Per joint: the child's origin in its parent's frame, or for a joint on a base (the seat, a hip mount),
        where the child's origin is in the world (the bases do not move), metres."""
        angles = np.zeros(N_DOF)
        for k, joint in enumerate(JOINTS):
            parent, child = JOINT_LINKS[joint]
            c = index[child]
            p = -1 if parent in BASE_LINKS else index[parent]
            self.rows.append((p, c))
            if p < 0:  # a base fixed on the throne, aligned with the world: the child's origin stays put
                local = rot[c]
                self.offsets[k] = ref[c, :3]
            else:
                local = rot[p].inv() * rot[c]
                self.offsets[k] = rot[p].inv().apply(ref[c, :3] - ref[p, :3])
            angles[3 * k: 3 * k + 3] = local.as_euler("XYZ")
        self.angles = angles
        """The joint angles of the reference pose (57,) radians."""
        self.held: list[tuple[int, int, np.ndarray, Rotation]] = []  # (row, carrier row, offset, rotation)
        for link, carrier in HELD_LINKS.items():
            if link in index and carrier in index:
                i, c = index[link], index[carrier]
                self.held.append((i, c, rot[c].inv().apply(ref[i, :3] - ref[c, :3]), rot[c].inv() * rot[i]))

    def pose(self, q: np.ndarray | None = None) -> np.ndarray:
        """Link frames (L, 7) with joint angles ``q`` (57,) radians (default: the reference pose's)."""
        q = self.angles if q is None else np.asarray(q, dtype=float)
        if q.shape != (N_DOF,):
            raise ValueError(f"expected {N_DOF} joint angles, got {q.size}")
        out = self.reference.copy()
        rots: dict[int, Rotation] = {}
        for k, (p, c) in enumerate(self.rows):
            local = Rotation.from_euler("XYZ", q[3 * k: 3 * k + 3])
            if p < 0:
                rots[c] = local
                out[c, :3] = self.offsets[k]
            else:
                rots[c] = rots[p] * local
                out[c, :3] = out[p, :3] + rots[p].apply(self.offsets[k])
            out[c, 3:] = rots[c].as_quat()
        for i, c, offset, local in self.held:
            out[i, :3] = out[c, :3] + rots[c].apply(offset)
            out[i, 3:] = (rots[c] * local).as_quat()
        return out

    def effectors(self, pose: np.ndarray) -> dict[str, tuple[float, float, float]]:
        """Stick tips and balls of the feet of a pose (L, 7): limb -> (x, y, z) metres."""
        out: dict[str, tuple[float, float, float]] = {}
        for limb, (link, offset) in self.info.effectors.items():
            if link in self.index:
                row = pose[self.index[link]]
                x, y, z = row[:3] + Rotation.from_quat(row[3:]).apply(offset)
                out[limb] = (float(x), float(y), float(z))
        return out

    def angles_from(self, edits: Mapping[str, Sequence[float]], base: np.ndarray | None = None) -> np.ndarray:
        """Joint angles (57,) radians: ``base`` (default: the reference) with ``edits`` {joint: (x, y, z) degrees}.

        Raises ``ValueError`` for an unknown joint or a non-finite or out-of-range angle (+-360 degrees).
        """
        q = (self.angles if base is None else base).copy()
        if not isinstance(edits, Mapping):
            raise ValueError("angles must be an object {joint: [x, y, z] degrees}")
        for joint, values in edits.items():
            if joint not in JOINTS:
                raise ValueError(f"unknown joint {joint!r} (the 19 joints: {', '.join(JOINTS)})")
            if not isinstance(values, Sequence) or len(values) != 3 or \
                    not all(isinstance(v, int | float) and math.isfinite(v) and -360 <= v <= 360 for v in values):
                raise ValueError(f"angles of {joint!r}: three numbers within +-360 degrees")
            k = JOINTS.index(joint)
            q[3 * k: 3 * k + 3] = np.radians(np.asarray(values, dtype=float))
        return q

    def key_pose(self, q: np.ndarray) -> KeyPose:
        """What the editor saves for angles ``q`` (57,) radians: every joint in degrees and the effectors."""
        joints = {j: tuple(round(float(math.degrees(a)), 3) for a in q[3 * k: 3 * k + 3]) for k, j in enumerate(JOINTS)}
        effectors = {limb: tuple(round(v, 5) for v in p) for limb, p in self.effectors(self.pose(q)).items()}
        return KeyPose.model_validate({"joints": joints, "effectors": effectors})

    def page_description(self, q: np.ndarray) -> dict[str, object]:
        """The editor's sliders for the page: joints, each DOF's name and limits (degrees), the angles (degrees)."""
        lo, hi = np.degrees(self.info.lower), np.degrees(self.info.upper)
        return {
            "joints": list(JOINTS),
            "dofs": {j: [[DOF_NAMES[3 * k + a], round(float(lo[3 * k + a]), 1), round(float(hi[3 * k + a]), 1)]
                         for a in range(len(AXES))] for k, j in enumerate(JOINTS)},
            "angles": {j: [round(float(math.degrees(v)), 2) for v in q[3 * k: 3 * k + 3]]
                       for k, j in enumerate(JOINTS)},
        }


def rest_poser() -> CharacterPoser:
    """The editor's body when no live one has been seen: the shipped snapshot's rest pose."""
    info = load_character()
    return CharacterPoser(info.names, info.rest, info)
