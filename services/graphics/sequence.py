"""A recorded or generated pose sequence: what the view, the exports and the video consume.

A :class:`PoseSequence` holds the poses of ``L`` links at ``N`` instants, in
the layout of ``/batteur/pose``: per link ``x y z qx qy qz qw`` (world metres,
unit quaternion, z up). Times are seconds on the rig clock, strictly
increasing. It is also the input of the kinematic (keyframe) preview: any
producer (physics recording, ``common.gesture`` keyframes, the synthetic
figure) hands the graphics service a ``PoseSequence``.
"""

from __future__ import annotations

import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from common.input_file import file_problem
from common.messages import Pose, Skeleton

FLOATS_PER_LINK = 7


def normalize_quats(q: np.ndarray) -> np.ndarray:
    """Unit quaternions along the last axis; a zero quaternion becomes identity. Shape kept."""
    q = np.asarray(q, dtype=float)
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    out = np.where(norm > 1e-12, q / np.maximum(norm, 1e-12), np.array([0.0, 0.0, 0.0, 1.0]))
    return out


def slerp(q0: np.ndarray, q1: np.ndarray, u: float | np.ndarray) -> np.ndarray:
    """Spherical linear interpolation of quaternions (..., 4) x y z w, ``u`` in [0, 1]."""
    q0 = normalize_quats(q0)
    q1 = normalize_quats(q1)
    dot = np.sum(q0 * q1, axis=-1, keepdims=True)
    q1 = np.where(dot < 0, -q1, q1)
    dot = np.abs(dot)
    u = np.asarray(u, dtype=float)
    if u.ndim:
        u = u[..., None]
    theta = np.arccos(np.clip(dot, -1.0, 1.0))
    sin = np.sin(theta)
    small = sin < 1e-6
    w0 = np.where(small, 1.0 - u, np.sin((1.0 - u) * theta) / np.where(small, 1.0, sin))
    w1 = np.where(small, u, np.sin(u * theta) / np.where(small, 1.0, sin))
    return normalize_quats(w0 * q0 + w1 * q1)


def interpolate_pose(a: np.ndarray, b: np.ndarray, u: float) -> np.ndarray:
    """Pose between ``a`` and ``b`` (L, 7): positions lerped, orientations slerped."""
    out = np.empty_like(a)
    out[:, :3] = a[:, :3] + (b[:, :3] - a[:, :3]) * u
    out[:, 3:] = slerp(a[:, 3:], b[:, 3:], u)
    return out


@dataclass
class PoseSequence:
    """Poses of ``L`` named links at ``N`` times.

    Attributes
    ----------
    names : list of str, length L
        Link names, as in ``/batteur/skeleton``.
    times : np.ndarray, shape (N,)
        Rig time of each pose, seconds, strictly increasing.
    values : np.ndarray, shape (N, L, 7)
        ``x y z`` (metres, world, z up) and ``qx qy qz qw`` per link.
    """

    names: list[str]
    times: np.ndarray
    values: np.ndarray

    def __post_init__(self) -> None:
        self.times = np.asarray(self.times, dtype=float)
        self.values = np.asarray(self.values, dtype=float)
        if self.times.ndim != 1:  # e.g. a hand-made --preview file: every frame would fail later
            raise ValueError(f"times must be a list of seconds, got an array of shape {self.times.shape}")
        if not np.all(np.isfinite(self.times)):
            raise ValueError("pose times must be finite")
        n, links = len(self.times), len(self.names)
        if self.values.shape != (n, links, FLOATS_PER_LINK):
            raise ValueError(f"values must have shape ({n}, {links}, 7), got {self.values.shape}")
        if n == 0:
            raise ValueError("a pose sequence needs at least one pose")
        if n > 1 and not np.all(np.diff(self.times) > 0):
            raise ValueError("pose times must be strictly increasing")
        if not np.all(np.isfinite(self.values)):
            raise ValueError("pose values must be finite")
        if len(set(self.names)) != links:
            raise ValueError("link names must be unique")

    @property
    def duration(self) -> float:
        """Seconds from the first to the last pose."""
        return float(self.times[-1] - self.times[0])

    def index(self, name: str) -> int:
        return self.names.index(name)

    def sample(self, t: float) -> np.ndarray:
        """The pose (L, 7) at rig time ``t`` seconds, interpolated; clamped at the ends."""
        times = self.times
        if t <= times[0]:
            return self.values[0].copy()
        if t >= times[-1]:
            return self.values[-1].copy()
        i = int(np.searchsorted(times, t, side="right")) - 1
        u = (t - times[i]) / (times[i + 1] - times[i])
        return interpolate_pose(self.values[i], self.values[i + 1], float(u))

    def resample_times(self, rate_hz: float, start: float | None = None, end: float | None = None) -> np.ndarray:
        """The rig times (seconds) :meth:`resample` samples at: ``start`` (default the first pose's), then every
        1 / ``rate_hz`` up to ``end`` (default the last pose's), as a BVH's frames."""
        t0 = self.times[0] if start is None else start
        t1 = self.times[-1] if end is None else end
        count = max(1, int(np.floor((t1 - t0) * rate_hz + 1e-9)) + 1)
        return t0 + np.arange(count) / rate_hz

    def resample(self, rate_hz: float, start: float | None = None, end: float | None = None,
                 on_progress: Callable[[int], None] | None = None) -> PoseSequence:
        """The sequence sampled at ``rate_hz`` from ``start`` to ``end`` (seconds, inclusive of start), into one
        array (a list of frames to stack held twice the memory: a long piece's glTF export). ``on_progress``:
        called with the frames done every 1,024 frames and at the end."""
        times = self.resample_times(rate_hz, start, end)
        count = len(times)
        values = np.empty((count, *self.values.shape[1:]))
        for k, t in enumerate(times):
            values[k] = self.sample(float(t))
            if on_progress is not None and k % 1024 == 0:
                on_progress(k)
        if on_progress is not None:
            on_progress(count)
        return PoseSequence(list(self.names), times, values)

    def skeleton_message(self, layout: int = 0) -> Skeleton:
        return Skeleton(layout=layout, names=tuple(self.names))

    def pose_messages(self, layout: int = 0) -> list[Pose]:
        """One ``/batteur/pose`` per instant, as physics would publish them."""
        return [
            Pose(time=float(t), layout=layout, values=tuple(float(v) for v in frame.ravel()))
            for t, frame in zip(self.times, self.values, strict=True)
        ]

    def save(self, path: Path) -> None:
        """Write as ``.npz`` (names, times, values)."""
        np.savez_compressed(path, names=np.array(self.names), times=self.times, values=self.values)

    @classmethod
    def load(cls, path: Path) -> PoseSequence:
        """Read a sequence written by :meth:`save`; ``ValueError`` if it is not one, or not a regular file (a
        folder, a device, a pipe: never opened, a pipe would wait for a writer)."""
        problem = file_problem(Path(path), "a pose sequence file (.npz)")
        if problem is not None:
            raise ValueError(f"{path}: {problem}")
        if not zipfile.is_zipfile(path):  # NumPy would speak of pickled data it refuses to load
            raise ValueError(f"{path}: not a pose sequence file (not an .npz archive)")
        try:
            with np.load(path, allow_pickle=False) as data:
                names = data["names"]
                if names.ndim != 1:
                    raise ValueError(f"names must be a list of link names, got an array of shape {names.shape}")
                return cls([str(n) for n in names], data["times"], data["values"])
        except (KeyError, OSError) as exc:
            raise ValueError(f"{path}: not a pose sequence file ({exc})") from exc
