"""Motion capture input: DeepMimic clips (real human motion shipped with pybullet_data); BVH files are read by
:mod:`services.physics.bvh_motion`.

DeepMimic's humanoid is y-up, facing +x, with +z to its right; a frame is
``[duration, root position (3), root rotation (4, w x y z), chest (4), neck
(4), right hip (4), right knee (1), right ankle (4), right shoulder (4), right
elbow (1), left hip (4), left knee (1), left ankle (4), left shoulder (4), left
elbow (1)]``, joint rotations local to the parent, knees and elbows one angle
about z. Its zero pose (standing, arms hanging) is ours, so a local rotation
maps to our body frame (x right, y forward, z up) by the fixed change of axes
``C``: ``R_ours = C R_dm C^T``. The chest rotation is shared equally by our
lumbar and thoracic joints, the neck's by our neck and head joints; DeepMimic
has no clavicles or wrists.
"""

from __future__ import annotations

import json
import logging
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pybullet_data
from scipy.spatial.transform import Rotation

from common.input_file import NO_SUCH_FILE, file_problem


class ClipError(ValueError):
    """A motion clip file that cannot be read as one (the message names it)."""

MOTIONS_DIR = Path(pybullet_data.getDataPath()) / "data" / "motions"

C_DM_TO_OURS = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
"""Columns: DeepMimic's x (forward), y (up), z (right) expressed in our axes."""

_LAYOUT: list[tuple[str, int]] = [
    ("chest", 4), ("neck", 4), ("right_hip", 4), ("right_knee", 1), ("right_ankle", 4), ("right_shoulder", 4),
    ("right_elbow", 1), ("left_hip", 4), ("left_knee", 1), ("left_ankle", 4), ("left_shoulder", 4), ("left_elbow", 1),
]
FRAME_LENGTH = 1 + 3 + 4 + sum(n for _, n in _LAYOUT)

log = logging.getLogger("batteur.physics.limits")
_GIMBAL_SAID: set[tuple[str, str]] = set()
"""(clip file, joint) pairs whose gimbal lock was logged (:meth:`MotionClip.euler`): said once per process (the
clip's name where it has no file); two files of one name in two folders are two clips."""

UPPER_BODY = ("lumbar", "thoracic", "neck", "head", "left_shoulder", "left_elbow", "right_shoulder", "right_elbow")
"""Our joints driven by a DeepMimic clip's upper body."""


@dataclass(frozen=True)
class MotionClip:
    """Joint rotations over time in our body convention.

    ``times``: (F,) seconds; ``rotations``: joint name -> :class:`scipy.spatial.transform.Rotation`
    of length F (the child's frame relative to the parent's, our axes).
    """

    name: str
    times: np.ndarray
    rotations: dict[str, Rotation]
    source: str = ""
    """The file it was read from, as given (a shipped DeepMimic clip: its name; "": made in memory): what tells two
    clips of one name apart, and what the notes about the clip name."""

    @property
    def rate_hz(self) -> float:
        return float(1.0 / np.median(np.diff(self.times))) if len(self.times) > 1 else 0.0

    def euler(self, joint: str) -> np.ndarray:
        """(F, 3) intrinsic x-y-z Euler angles (radians) of a joint, as our three revolute DOF see them.

        Frames at gimbal lock (y at +-90 degrees: x and z turn about one axis) get the whole turn in x, z 0, as
        scipy does; that is logged once per clip and joint in plain words instead of scipy's warning, naming the
        clip by its file as given (two walk.bvh of two folders told apart), else its name."""
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            angles = np.asarray(self.rotations[joint].as_euler("XYZ"))
        locked = False
        for w in caught:
            if "gimbal lock" in str(w.message).lower():
                locked = True
            else:  # another warning: as it would have been
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        said = (self.source or self.name, joint)
        if locked and said not in _GIMBAL_SAID:
            _GIMBAL_SAID.add(said)
            at_lock = int(np.count_nonzero(np.abs(np.abs(angles[:, 1]) - np.pi / 2) < 1e-6)) if angles.ndim == 2 \
                else 1
            frames = len(angles) if angles.ndim == 2 else 1
            log.warning("clip %s: joint %s is at gimbal lock (its y angle at 90 degrees) in %d of %d frames: its x "
                        "and z angles cannot be told apart there; the whole turn was given to x (z 0) for its "
                        "limits", self.source or self.name, joint, max(at_lock, 1), frames)
        return angles

    def quaternions(self, joint: str) -> np.ndarray:
        """(F, 4) unit quaternions (x, y, z, w) of a joint."""
        return np.asarray(self.rotations[joint].as_quat())


def _to_ours(rot: Rotation) -> Rotation:
    c = Rotation.from_matrix(C_DM_TO_OURS)
    return c * rot * c.inv()


def _half(rot: Rotation) -> Rotation:
    return Rotation.from_rotvec(rot.as_rotvec() / 2.0)


def frame_column(column: int) -> str:
    """What column ``column`` (0-based) of a DeepMimic frame holds, e.g. ``"right_hip w"``."""
    names = ["duration", "root x", "root y", "root z", "root rotation w", "root rotation x", "root rotation y",
             "root rotation z"]
    for joint, n in _LAYOUT:
        names += [f"{joint} {c}" for c in "wxyz"] if n == 4 else [f"{joint} angle"]
    return names[column] if 0 <= column < len(names) else f"column {column + 1}"


def deepmimic_clip_names() -> list[str]:
    """Names of the humanoid clips shipped with pybullet_data (e.g. 'punch', 'dance_a')."""
    return sorted(p.stem.removeprefix("humanoid3d_") for p in MOTIONS_DIR.glob("humanoid3d_*.txt"))


def load_deepmimic(name_or_path: str | Path) -> MotionClip:
    """Read a DeepMimic humanoid clip: a shipped clip's name such as ``"punch"`` (whatever the current folder holds
    of that name), else a path.

    Raises ``FileNotFoundError`` naming the shipped clips, :class:`ClipError` (a ``ValueError``) for a malformed
    file or a path that is not a regular file (a folder, a device, a pipe: never opened).
    """
    path = Path(name_or_path)
    if not path.suffix and str(name_or_path) in deepmimic_clip_names():
        path = MOTIONS_DIR / f"humanoid3d_{name_or_path}.txt"
    problem = file_problem(path, "a DeepMimic clip file", give="a DeepMimic clip file or a shipped clip's name")
    if problem == NO_SUCH_FILE:
        raise FileNotFoundError(f"no clip {str(name_or_path)!r} (shipped: {', '.join(deepmimic_clip_names())})")
    if problem is not None:
        raise ClipError(f"{name_or_path}: {problem}")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except ValueError as exc:  # not UTF-8, not JSON
        raise ClipError(f"{path.name}: not a DeepMimic clip (JSON with 'Frames'): {exc}") from None
    if not isinstance(data, dict):
        raise ClipError(f"{path.name}: not a DeepMimic clip (JSON with 'Frames')")
    try:
        frames = np.asarray(data.get("Frames", []), dtype=float)
    except (TypeError, ValueError) as exc:  # ragged rows, strings
        raise ClipError(f"{path.name}: frames are not rows of numbers ({exc})") from None
    if frames.ndim != 2 or frames.shape[1] != FRAME_LENGTH or len(frames) < 2:
        raise ClipError(f"{path.name}: expected frames of {FRAME_LENGTH} values, got shape {frames.shape}")
    if not np.all(np.isfinite(frames)):
        frame, column = (int(v) for v in np.argwhere(~np.isfinite(frames))[0])
        raise ClipError(f"{path.name}: frame {frame + 1} of {len(frames)}, value {column + 1} ({frame_column(column)}; "
                        f"both counted from 1) is not finite ({frames[frame, column]})")
    times = np.concatenate([[0.0], np.cumsum(frames[:-1, 0])])
    col = 8
    rotations: dict[str, Rotation] = {}
    for joint, n in _LAYOUT:
        block = frames[:, col:col + n]
        col += n
        if n == 4:
            rot = Rotation.from_quat(block[:, [1, 2, 3, 0]])  # w x y z -> x y z w
        else:
            rot = Rotation.from_rotvec(np.column_stack([np.zeros(len(block)), np.zeros(len(block)), block[:, 0]]))
        rot = _to_ours(rot)
        if joint == "chest":
            rotations["lumbar"] = rotations["thoracic"] = _half(rot)
        elif joint == "neck":
            rotations["neck"] = rotations["head"] = _half(rot)
        else:
            rotations[joint] = rot
    name = path.stem.removeprefix("humanoid3d_")
    shipped = path.parent == MOTIONS_DIR and str(name_or_path) == name  # named, not a path: said by its name
    return MotionClip(name, times, rotations, name if shipped else str(path))
