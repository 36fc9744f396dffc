"""Joint limits from motion capture, in both formulations of Bouënard et al. (2009).

* Euler statistics: per DOF (our intrinsic x-y-z angles) the mean, standard
  deviation and the range seen in the data, widened by a margin. Enforced by
  PyBullet as the revolute joints' limits.
* Quaternion formulation (the paper's Algorithm 1): the mean orientation
  ``q_mean`` of the samples (Markley's eigenvector method), the log map of
  each sample into the tangent space at the mean, ``v_k = log(q_mean^-1 q_k)``
  (rotation vectors, radians), the SVD of the stacked ``v_k`` giving the
  principal axes and the spread along them; the limit is the ellipsoid
  ``sum_i (v . a_i / e_i)^2 <= 1`` whose extents ``e_i`` contain a chosen
  share of the samples. Enforced in simulation by projecting targets onto it
  and by a restoring torque when the joint leaves it
  (:meth:`QuaternionLimit.project`).
"""

from __future__ import annotations

import dataclasses
import logging
import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from services.physics.character import JOINTS, joint_kind
from services.physics.mocap import MotionClip, deepmimic_clip_names, load_deepmimic

log = logging.getLogger("batteur.physics.limits")

ANATOMICAL_DEG: dict[str, tuple[float, float, float, float, float, float]] = {
    "seat": (-30, 30, -15, 15, -30, 30),
    "lumbar": (-45, 20, -20, 20, -25, 25),
    "thoracic": (-35, 20, -20, 20, -30, 30),
    "neck": (-45, 40, -30, 30, -55, 55),
    "head": (-35, 30, -20, 20, -45, 45),
    "clavicle": (-20, 20, -20, 20, -15, 15),
    "shoulder": (-60, 180, -180, 40, -90, 90),
    "elbow": (0, 150, -10, 10, -100, 100),
    "wrist": (-75, 80, -35, 35, -25, 25),
    "hip": (-20, 130, -45, 20, -45, 45),
    "knee": (-150, 0, -8, 8, -25, 25),
    "ankle": (-50, 30, -25, 25, -30, 30),
}
"""Anatomical ranges, degrees: (x lo, x hi, y lo, y hi, z lo, z hi), right side.

Signs (see services/physics/character.py): +x flexes a limb forward (hip,
shoulder, elbow) and extends the spine backward; knee flexion is -x; +y swings
a hanging segment toward -x (so right abduction is -y); z is the long-axis
rotation. Left-side y and z ranges are mirrored.
"""


@dataclass(frozen=True)
class EulerLimit:
    """Per-DOF statistics of a joint's intrinsic x-y-z Euler angles, radians (each (3,))."""

    lower: np.ndarray
    upper: np.ndarray
    mean: np.ndarray
    std: np.ndarray

    def contains(self, euler: np.ndarray) -> np.ndarray:
        """(N,) bool: samples (N, 3) inside the box."""
        e = np.atleast_2d(euler)
        return np.all((e >= self.lower - 1e-12) & (e <= self.upper + 1e-12), axis=1)

    def union(self, other: EulerLimit) -> EulerLimit:
        return EulerLimit(np.minimum(self.lower, other.lower), np.maximum(self.upper, other.upper),
                          (self.mean + other.mean) / 2, np.maximum(self.std, other.std))


def euler_limits(euler: np.ndarray, margin_rad: float = 0.0) -> EulerLimit:
    """Euler statistics of samples (N, 3) radians: the range seen, widened by ``margin_rad``."""
    e = np.asarray(euler, dtype=float)
    if e.ndim != 2 or e.shape[1] != 3 or len(e) == 0 or not np.all(np.isfinite(e)):
        raise ValueError(f"euler samples must be a finite (N, 3) array, got shape {e.shape}")
    return EulerLimit(e.min(axis=0) - margin_rad, e.max(axis=0) + margin_rad, e.mean(axis=0), e.std(axis=0))


def mean_quaternion(quats: np.ndarray) -> np.ndarray:
    """Average orientation of unit quaternions (N, 4) x y z w (Markley et al. 2007): (4,)."""
    q = np.asarray(quats, dtype=float)
    m = q.T @ q / len(q)
    w, v = np.linalg.eigh(m)
    mean = v[:, int(np.argmax(w))]
    return mean if mean[3] >= 0 else -mean


@dataclass(frozen=True)
class QuaternionLimit:
    """Algorithm 1's limit: mean (4,) x y z w, principal axes (3, 3) as columns, extents (3,) radians."""

    mean: np.ndarray
    axes: np.ndarray
    extents: np.ndarray

    def tangent(self, quats: np.ndarray) -> np.ndarray:
        """Log map at the mean: rotation vectors (N, 3) of ``mean^-1 q``, radians."""
        rel = Rotation.from_quat(self.mean).inv() * Rotation.from_quat(np.atleast_2d(quats))
        return np.asarray(rel.as_rotvec())

    def radius(self, quats: np.ndarray) -> np.ndarray:
        """(N,) normalised ellipsoid radius: <= 1 inside the limit."""
        coords = self.tangent(quats) @ self.axes
        return np.sqrt(np.sum((coords / self.extents) ** 2, axis=1))

    def contains(self, quats: np.ndarray) -> np.ndarray:
        return self.radius(quats) <= 1.0 + 1e-9

    def project(self, quats: np.ndarray) -> np.ndarray:
        """The nearest-along-the-ray orientation inside the limit (unchanged when inside): (N, 4)."""
        v = self.tangent(quats)
        r = np.sqrt(np.sum(((v @ self.axes) / self.extents) ** 2, axis=1))
        scale = np.where(r > 1.0, 1.0 / np.maximum(r, 1e-12), 1.0)
        inside = Rotation.from_quat(self.mean) * Rotation.from_rotvec(v * scale[:, None])
        return np.asarray(inside.as_quat())


def quaternion_limits(quats: np.ndarray, coverage: float = 0.999, min_extent_rad: float = math.radians(4.0),
                      margin: float = 1.05) -> QuaternionLimit:
    """Algorithm 1: mean quaternion, log map, SVD -> principal axes and extents.

    Parameters
    ----------
    quats : np.ndarray, shape (N, 4)
        Unit quaternions x y z w of one joint over a clip.
    coverage : float
        Share of the samples the ellipsoid must contain (before ``margin``).
    min_extent_rad : float
        Smallest extent along an axis, radians (a joint the clip barely moves
        about an axis still gets a little play).
    margin : float
        Multiplier on the extents.
    """
    q = np.asarray(quats, dtype=float)
    if q.ndim != 2 or q.shape[1] != 4 or len(q) < 3 or not np.all(np.isfinite(q)):
        raise ValueError(f"quaternions must be a finite (N >= 3, 4) array, got shape {q.shape}")
    if not 0.5 <= coverage <= 1.0:
        raise ValueError(f"coverage must be in [0.5, 1], got {coverage}")
    mean = mean_quaternion(q)
    v = np.asarray((Rotation.from_quat(mean).inv() * Rotation.from_quat(q)).as_rotvec())
    centred = v - v.mean(axis=0)
    _, sing, vt = np.linalg.svd(centred, full_matrices=False)
    axes = vt.T
    sigma = np.maximum(sing / math.sqrt(len(v)), 1e-6)
    coords = v @ axes
    # scale the sigma-shaped ellipsoid so that `coverage` of the samples are inside it
    radius = np.sqrt(np.sum((coords / sigma) ** 2, axis=1))
    k = float(np.quantile(radius, coverage))
    extents = np.maximum(k * sigma * margin, min_extent_rad)
    return QuaternionLimit(mean, axes, extents)


DOF_SOURCES = ("mocap", "still", "wraps", "anatomical")
"""Where a DOF's range comes from (:attr:`JointLimits.dof_sources`): the clips' range plus the margin; the
anatomical range because the clips hardly move it (``still``) or because its Euler angle wraps around
(``wraps``); the anatomical range of a joint the clips lack."""


@dataclass(frozen=True)
class JointLimits:
    """Limits of every joint: the Euler box (enforced as revolute limits) and, where mocap had the joint,
    the quaternion ellipsoid (enforced by the controller).

    ``sources``: joint -> ``mocap``, ``mocap+anatomical`` (some DOF anatomical) or ``anatomical``, with
    ``+symmetric`` or ``+mirrored`` where :func:`symmetric_limits` changed the box (cut to the common range, or
    given what either side moved through) and ``+posture`` where the box was grown to the playing posture (and the
    ellipsoid dropped)."""

    euler: dict[str, EulerLimit]
    quaternion: dict[str, QuaternionLimit]
    sources: dict[str, str]
    dof_sources: dict[str, tuple[str, str, str]] = field(default_factory=dict)
    """Joint -> the source of its x, y and z ranges, each one of :data:`DOF_SOURCES`."""
    dropped: tuple[str, ...] = ()
    """Joints whose quaternion limit was dropped because the playing posture lies outside the clips' motion
    (``must_contain``): their grown Euler box limits them alone."""
    symmetric: bool = False
    """Each left/right pair's Euler boxes were made mirror images (:func:`symmetric_limits`; a box grown to the
    playing posture afterwards, ``+posture``, may reach further on its own side); False: each side's own estimate."""

    def formulations(self) -> dict[str, dict[str, Any]]:
        """Joint -> ``formulation`` (``euler+quaternion``: the box and Algorithm 1's ellipsoid; ``euler``: the box
        alone), ``source`` (:attr:`sources`) and ``dofs`` (:attr:`dof_sources`, x y z), for reports."""
        return {joint: {"formulation": "euler+quaternion" if joint in self.quaternion else "euler",
                        "source": self.sources[joint],
                        "dofs": list(self.dof_sources.get(joint, ("anatomical",) * 3))}
                for joint in self.euler}

    def dropped_summary(self) -> str | None:
        """One line naming the joints that lost their quaternion limit to the playing posture (None: none did)."""
        if not self.dropped:
            return None
        kept = ", ".join(self.quaternion) or "none"
        return (f"the playing posture lies outside the clips' motion at {', '.join(self.dropped)}: their quaternion "
                "limits (Algorithm 1) are dropped and their Euler boxes, grown to hold the posture, limit them alone "
                f"(quaternion limits kept: {kept})")

    def dof_limits(self) -> dict[str, tuple[float, float]]:
        """DOF name -> (lower, upper) radians, for the URDF."""
        out: dict[str, tuple[float, float]] = {}
        for joint, lim in self.euler.items():
            for i, axis in enumerate("xyz"):
                out[f"{joint}_{axis}"] = (float(lim.lower[i]), float(lim.upper[i]))
        return out


def anatomical_limit(joint: str) -> EulerLimit:
    lo_x, hi_x, lo_y, hi_y, lo_z, hi_z = ANATOMICAL_DEG[joint_kind(joint)]
    if joint.startswith("left_"):
        lo_y, hi_y = -hi_y, -lo_y
        lo_z, hi_z = -hi_z, -lo_z
    lower = np.radians([lo_x, lo_y, lo_z])
    upper = np.radians([hi_x, hi_y, hi_z])
    return EulerLimit(lower, upper, (lower + upper) / 2, (upper - lower) / 4)


def limits_from_clips(clips: Iterable[MotionClip], margin_rad: float = math.radians(5.0),
                      coverage: float = 0.999, must_contain: dict[str, np.ndarray] | None = None,
                      symmetric: bool = False) -> JointLimits:
    """Joint limits of the 19 joints from motion clips, anatomical ranges where the clips have no data.

    For a joint the clips drive, the Euler box is the range seen (plus
    ``margin_rad``) and the quaternion ellipsoid comes from Algorithm 1 on all
    the clips' samples; a DOF the clips hardly move (range under 10 degrees,
    like a DeepMimic knee's y and z: ``still``) or whose angle wraps around (range over 300 degrees: ``wraps``)
    keeps its anatomical range (``dof_sources``), and a joint with a still DOF (a 1-DOF elbow or knee, a spine
    a clip holds still) gets no ellipsoid.
    ``must_contain``: joint -> Euler angles (3,) that must lie inside (the
    playing posture); the box grows to include them, and a joint whose box or ellipsoid did not hold them
    keeps the box only (recorded in ``sources`` as ``+posture``; ``dropped`` names those that had an ellipsoid).
    ``symmetric``: the clips' boxes are made mirror-symmetric (:func:`symmetric_limits`) before they grow to
    ``must_contain``: the posture is a requirement, not an estimate of one side's range, so it is held as it is.
    """
    samples_e: dict[str, list[np.ndarray]] = {}
    samples_q: dict[str, list[np.ndarray]] = {}
    for clip in clips:
        for joint in clip.rotations:
            samples_e.setdefault(joint, []).append(clip.euler(joint))
            samples_q.setdefault(joint, []).append(clip.quaternions(joint))
    euler: dict[str, EulerLimit] = {}
    quaternion: dict[str, QuaternionLimit] = {}
    sources: dict[str, str] = {}
    dof_sources: dict[str, tuple[str, str, str]] = {}
    for joint in JOINTS:
        anat = anatomical_limit(joint)
        if joint in samples_e:
            mocap = euler_limits(np.concatenate(samples_e[joint]), margin_rad)
            span = mocap.upper - mocap.lower
            # a DOF the clips hardly move keeps its anatomical range; so does one whose Euler angle wraps
            # around (arms over the head in a cartwheel): an Euler box cannot express it, the quaternion limit can
            tiny = span < math.radians(10.0) + 2 * margin_rad
            wraps = span > math.radians(300.0)
            lower = np.where(tiny | wraps, anat.lower, mocap.lower)
            upper = np.where(tiny | wraps, anat.upper, mocap.upper)
            euler[joint] = EulerLimit(lower, upper, mocap.mean, mocap.std)
            if not np.any(tiny):
                quaternion[joint] = quaternion_limits(np.concatenate(samples_q[joint]), coverage)
            sources[joint] = "mocap" if not np.any(tiny | wraps) else "mocap+anatomical"
            kinds = ["still" if t else "wraps" if w else "mocap" for t, w in zip(tiny, wraps, strict=True)]
            dof_sources[joint] = (kinds[0], kinds[1], kinds[2])
        else:
            euler[joint] = anat
            sources[joint] = "anatomical"
            dof_sources[joint] = ("anatomical",) * 3
    limits = JointLimits(euler, quaternion, sources, dof_sources)
    if symmetric:
        limits = symmetric_limits(limits)
    return hold_posture(limits, must_contain, margin_rad) if must_contain else limits


def hold_posture(limits: JointLimits, must_contain: dict[str, np.ndarray], margin_rad: float) -> JointLimits:
    """``limits`` grown to hold ``must_contain`` (joint -> Euler angles (3,), radians: the playing posture): a box
    that does not hold them grows to them plus ``margin_rad``, and a joint whose box or ellipsoid did not hold them
    keeps the box only (``+posture`` in its sources; ``dropped`` names those that had an ellipsoid)."""
    euler, quaternion, sources = dict(limits.euler), dict(limits.quaternion), dict(limits.sources)
    dropped = list(limits.dropped)
    for joint in JOINTS:
        if joint not in must_contain or joint not in euler:
            continue
        need = np.asarray(must_contain[joint], dtype=float)
        lim = euler[joint]
        outside = not bool(lim.contains(need)[0])
        if outside:
            euler[joint] = EulerLimit(np.minimum(lim.lower, need - margin_rad),
                                      np.maximum(lim.upper, need + margin_rad), lim.mean, lim.std)
        ellipsoid = quaternion.get(joint)
        if ellipsoid is not None:
            outside |= not bool(ellipsoid.contains(Rotation.from_euler("XYZ", need).as_quat()[None])[0])
        if outside:  # the grown box only: an ellipsoid of the clips' motion does not reach the posture
            sources[joint] += "+posture"
            if quaternion.pop(joint, None) is not None:
                dropped.append(joint)
    return dataclasses.replace(limits, euler=euler, quaternion=quaternion, sources=sources, dropped=tuple(dropped))


MIRROR_SIGNS = np.array([1.0, -1.0, -1.0])
"""A joint's x y z angles mirrored onto the other side (through the sagittal plane): x kept, y and z negated."""


def mirrored_limit(lim: EulerLimit) -> EulerLimit:
    """The Euler box of ``lim``'s joint mirrored onto the other side (``MIRROR_SIGNS``, as ``anatomical_limit``)."""
    keep = MIRROR_SIGNS > 0
    return EulerLimit(np.where(keep, lim.lower, -lim.upper), np.where(keep, lim.upper, -lim.lower),
                      lim.mean * MIRROR_SIGNS, lim.std.copy())


ONE_SIDED_SHARE = 0.5
"""A DOF is one-sided (:func:`symmetric_limits`) when the range both sides share is under this share of the wider
side's, or when one side barely moves it (``still``) and the other does. The 15 DeepMimic clips share at least 0.79
on every DOF (the default limits stay the common range); ``punch``'s striking right elbow shares 0.61 and is still
cut to the common range (126 -> 77 degrees): a clip of one arm wants ``--asymmetric-limits``."""


def symmetric_limits(limits: JointLimits) -> JointLimits:
    """``limits`` with each left/right pair's Euler boxes the same on both sides, mirrored: per DOF the range both
    sides' estimates agree on (the right box cut to the mirrored left one; where they share no range, their union).

    Clips favour a side (a kick, a punch): the 15 DeepMimic clips let the right ankle flex 66.8 degrees up (+x) and
    the left 59.0; under 16th-note kicks at 140 bpm the IK's posture drifts stroke by stroke toward that bound
    (ankle up, knee opened, hip lowered), and at 66.8 the toe no longer presses the footboard: 5 kicks sounded of 32,
    the mirrored left foot played all (docs/physics.md, "Symmetric limits"). The union of both sides (66.8 on
    both) made the left foot fail as well. The quaternion ellipsoids stay each side's own (not implicated). A joint
    whose box this changes has ``+symmetric`` added to its ``sources``.

    A one-sided clip (``punch``: the right arm strikes, the left hangs) is another matter: the idle side's narrow
    range is the absence of data, not a limit, and the common range crippled the moving side (the right shoulder's
    216, 80 and 180 degrees cut to 76, 35 and 44). A DOF is one-sided when the common range is under
    :data:`ONE_SIDED_SHARE` of the wider side's range, or one side barely moves it (``still``, its box anatomical)
    and the other does: there both sides take what either side did (the moving side's range, mirrored, grown to the
    other side's where it reached elsewhere, as the kick's standing and kicking hips), and where one side is still,
    the moving side's range. Such a joint has ``+mirrored`` in its ``sources`` (instead of ``+symmetric``), and the
    ellipsoid of the side that moved less in those DOFs is dropped: it holds that side's few samples, not its range
    (the box limits it alone). None of the shipped DeepMimic clips' pairs is one-sided taken together (the default
    limits are the common range throughout). One warning names the one-sided joints."""
    euler, sources = dict(limits.euler), dict(limits.sources)
    quaternion = dict(limits.quaternion)
    one_sided: list[str] = []
    idle_ellipsoids: list[str] = []  # the quaternion limits of the side that moved less, dropped
    for joint in JOINTS:
        kind = joint[len("right_"):]
        if not joint.startswith("right_") or f"left_{kind}" not in euler:
            continue
        right, left = euler[joint], mirrored_limit(euler[f"left_{kind}"])
        lower, upper = np.maximum(right.lower, left.lower), np.minimum(right.upper, left.upper)
        apart = lower > upper  # no common range: the union (never seen with the shipped clips)
        lower = np.where(apart, np.minimum(right.lower, left.lower), lower)
        upper = np.where(apart, np.maximum(right.upper, left.upper), upper)
        src_r = limits.dof_sources.get(joint, ("anatomical",) * 3)
        src_l = limits.dof_sources.get(f"left_{kind}", ("anatomical",) * 3)
        wide_r, wide_l = right.upper - right.lower, left.upper - left.lower
        moved_r = moved_l = 0.0  # the one-sided DOFs' widths each side moved, radians
        mirrored = False
        for i in range(3):
            if "anatomical" in (src_r[i], src_l[i]) or src_r[i] == src_l[i] == "still":
                continue  # no data on a side, or on neither: nothing to tell
            if "still" in (src_r[i], src_l[i]):  # one side barely moves it: the moving side's range
                lower[i], upper[i] = (left.lower[i], left.upper[i]) if src_r[i] == "still" else \
                    (right.lower[i], right.upper[i])
                moved_r += 0.0 if src_r[i] == "still" else float(wide_r[i])
                moved_l += 0.0 if src_l[i] == "still" else float(wide_l[i])
            elif upper[i] - lower[i] < ONE_SIDED_SHARE * max(wide_r[i], wide_l[i]) and not apart[i]:
                lower[i], upper[i] = min(right.lower[i], left.lower[i]), max(right.upper[i], left.upper[i])
                moved_r, moved_l = moved_r + float(wide_r[i]), moved_l + float(wide_l[i])
            else:
                continue
            mirrored = True
        euler[joint] = EulerLimit(lower, upper, (right.mean + left.mean) / 2, np.maximum(right.std, left.std))
        euler[f"left_{kind}"] = mirrored_limit(euler[joint])
        if mirrored:
            one_sided.append(kind)
            idle = joint if moved_r < moved_l else f"left_{kind}"
            if quaternion.pop(idle, None) is not None:
                idle_ellipsoids.append(idle)
        for side in (joint, f"left_{kind}"):
            was, now = limits.euler[side], euler[side]
            if not (np.allclose(was.lower, now.lower) and np.allclose(was.upper, now.upper)):
                sources[side] += "+mirrored" if mirrored else "+symmetric"
    if one_sided:
        dropped = f"; the quaternion limits of {', '.join(idle_ellipsoids)} are dropped" if idle_ellipsoids else ""
        log.warning("the clips move one side much more than the other at %s: there both sides take the range either "
                    "side moved through, mirrored (the idle side's narrow range is no limit%s; --asymmetric-limits "
                    "keeps each side's own)", ", ".join(one_sided), dropped)
    return dataclasses.replace(limits, euler=euler, quaternion=quaternion, sources=sources, symmetric=True)


def load_clip(source: str | Path) -> MotionClip:
    """A motion clip in our joints: a BVH file (``.bvh``, :mod:`services.physics.bvh_motion`), a DeepMimic
    clip file, or a DeepMimic clip shipped with pybullet (a name such as ``"punch"``).

    Raises ``FileNotFoundError`` for a missing file or unknown name, ``ValueError`` naming the file for one that
    cannot be read as motion."""
    from services.physics.bvh_motion import load_bvh_clip

    if Path(source).suffix.lower() == ".bvh":
        if not Path(source).exists():
            raise FileNotFoundError(f"no BVH file {str(source)!r}")
        return load_bvh_clip(source)  # a folder, device or pipe: read_bvh says which
    return load_deepmimic(source)


def default_limits(clips: Iterable[str | Path] | None = None) -> JointLimits:
    """Limits from motion clips (:func:`load_clip`: BVH files, DeepMimic files or names); by default every
    DeepMimic humanoid clip shipped with pybullet."""
    names = list(clips) if clips is not None else deepmimic_clip_names()
    if not names:
        raise ValueError("no motion clip to take joint limits from")
    return limits_from_clips([load_clip(n) for n in names])
