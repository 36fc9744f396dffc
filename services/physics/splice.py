"""Splicing gesture plans into the drummer's tracks without a jump (the score player's re-plans, stops, live notes).

:func:`splice_plan` replaces each limb's track from a rig time ``t_s`` on: the track's own position and
velocity at ``t_s`` become a knot, then the plan's knots follow (at once where the plan agrees with the track,
else after a blend of up to :data:`BLEND_S`; a plan that starts later is joined from the track's state, braked
first when there is room). :func:`splice_window` replaces knots only from ``t_s`` to each limb's
:func:`join_time` and keeps the queued knots and strikes after it (a live note's window plan). Everything is
checked (reach, each track's room) before any track changes. Times are rig seconds, positions metres.
"""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING

import numpy as np

from common.gesture.plan import GesturePlan, HeadTrajectory, LimbTrajectory, hermite
from common.kit import Limb
from services.physics.follow_through import follows_through, strike_of
from services.physics.targets import TargetError, Track

if TYPE_CHECKING:
    from services.physics.drummer import DrummerScene

BLEND_S = 0.1
"""Where a re-plan disagrees with a limb's track, its knots within this long after the splice are dropped, s."""
BRAKE_S = 0.12
"""A moving limb is braked to a stop over this long (pause, stop, or before a plan that starts later), s."""
KNOT_TIME_S = 1e-9
"""Knots of two plans this close in time are the same knot (both come from the same note times), seconds."""
AGREE_M = 1e-3
AGREE_M_S = 0.02
"""A plan agrees with a track at the splice when positions are within ``AGREE_M`` metres and velocities
within ``AGREE_M_S`` m/s."""


def splice_plan(scene: DrummerScene, plan: GesturePlan, t_s: float, limbs: set[Limb] | None = None,
                blend_s: float = BLEND_S, brake_s: float = BRAKE_S) -> None:
    """Replace the drummer's tracks with ``plan`` from rig time ``t_s`` on, without a jump (module docstring).

    ``plan`` times are rig seconds. ``limbs``: only these limbs (default: every limb of the plan).
    Raises :class:`TargetError` (nothing queued, no track changed) when a knot after ``t_s`` is out of a limb's
    reach or a limb's track would hold more knots than its bound (``Track.max_knots``).
    """
    chosen = [(limb, traj) for limb, traj in plan.trajectories.items() if limbs is None or limb in limbs]
    _check_reach(scene, chosen, t_s, math.inf)
    splices = plan_splices(scene, plan, chosen, t_s, blend_s, brake_s)
    for (limb, _), splice in zip(chosen, splices, strict=True):  # every splice checked before any track changes
        track = scene.limb_tracks[limb.value]
        track.check_room(t_s, 1 + len(splice.bridge) + int(np.count_nonzero(splice.keep)))
    for (limb, traj), splice in zip(chosen, splices, strict=True):
        track = scene.limb_tracks[limb.value]
        track.add(t_s, splice.p0, splice.v0)  # cuts the track's knots at and after t_s
        for t, p in splice.bridge:
            track.add(t, p, np.zeros(3))
        keep = splice.keep
        if np.any(keep):
            _append(track, traj.times[keep], traj.positions[keep], traj.velocities[keep])
            track.add_strokes(plan.strokes_of(limb), 0.0, after=splice.cut)
    if plan.head is not None:
        scene.head = (plan.head, 0.0)


def _check_reach(scene: DrummerScene, chosen: list[tuple[Limb, LimbTrajectory]], t_s: float, until: float) -> None:
    """Raise :class:`TargetError` if a limb is unknown or a knot of its trajectory after ``t_s`` (and before
    ``until``) seconds is out of its reach (the scene's ``check_cartesian``, for every knot at once)."""
    for limb, traj in chosen:
        if limb.value not in scene.limb_tracks:
            raise TargetError(f"plan has unknown limb {limb.value!r}")
        scene.check_cartesian_rows(limb.value, traj.positions[(traj.times > t_s) & (traj.times < until)])


def plan_splices(scene: DrummerScene, plan: GesturePlan, chosen: list[tuple[Limb, LimbTrajectory]], t_s: float,
             blend_s: float, brake_s: float) -> list[_Splice]:
    """How each chosen limb's trajectory joins its track (or, for an empty track, the scene's targets) at ``t_s``."""
    first_stroke: dict[Limb, float] = {}
    for stroke in plan.strokes:
        if stroke.time > t_s and stroke.limb not in first_stroke:
            first_stroke[stroke.limb] = stroke.time
    here: dict[str, np.ndarray] | None = None
    splices: list[_Splice] = []
    for limb, traj in chosen:
        track = scene.limb_tracks[limb.value]
        if len(track):
            p0, v0 = (np.array(a, dtype=float) for a in track.sample(t_s))
        else:
            if here is None:
                here = scene.current_targets()
            p0, v0 = here[limb.value].copy(), np.zeros(3)
        splices.append(_splice(traj, t_s, p0, v0, first_stroke.get(limb, math.inf) - t_s, blend_s, brake_s))
    return splices


def splice_window(scene: DrummerScene, plan: GesturePlan, t_s: float, joins: dict[Limb, float],
                  head_until: float) -> None:
    """Splice a window's plan (a live note's) at rig time ``t_s`` as :func:`splice_plan` does, but on each limb of
    ``joins`` only until its join time ``t_j`` (s): from there on the queued knots and strikes stay (the window
    re-joins the queued plan there, :func:`join_time`). The head follows the window's plan until ``head_until``
    (s) and the queued head after it. Raises :class:`TargetError` (no track changed) as :func:`splice_plan`."""
    chosen = [(limb, plan.trajectories[limb]) for limb in joins]
    for limb, traj in chosen:
        _check_reach(scene, [(limb, traj)], t_s, joins[limb])
    splices = plan_splices(scene, plan, chosen, t_s, BLEND_S, BRAKE_S)
    spans: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    for (limb, traj), splice in zip(chosen, splices, strict=True):  # every span checked before any track changes
        t_j = joins[limb]
        keep = splice.keep & (traj.times < t_j)
        times = np.concatenate([[t_s], [t for t, _ in splice.bridge], traj.times[keep]])
        values = np.concatenate([splice.p0[None, :], *[p[None, :] for _, p in splice.bridge], traj.positions[keep]])
        velocities = np.concatenate([splice.v0[None, :], np.zeros((len(splice.bridge), 3)), traj.velocities[keep]])
        spans.append(scene.limb_tracks[limb.value].check_span(times, values, velocities, t_j))
    for (limb, _), splice, (times, values, velocities) in zip(chosen, splices, spans, strict=True):
        t_j = joins[limb]
        strikes = [strike_of(s, 0.0) for s in plan.strokes_of(limb) if splice.cut < s.time < t_j and follows_through(s)]
        scene.limb_tracks[limb.value].replace_span(times, values, velocities, t_j, strikes)
    if plan.head is not None:
        scene.head = (_joined_head(plan.head, scene.head, head_until), 0.0)


def _joined_head(new: HeadTrajectory, queued: tuple[HeadTrajectory, float] | None, until: float) -> HeadTrajectory:
    """The window's head trajectory (rig times) before ``until`` seconds, the queued one (its times plus its
    offset) from there on."""
    if queued is None:
        return new
    old, offset = queued
    mine = new.times < until
    theirs = old.times + offset >= until
    if not np.any(theirs):
        return new
    return HeadTrajectory(np.concatenate([new.times[mine], old.times[theirs] + offset]),
                          np.concatenate([new.targets[mine], old.targets[theirs]]),
                          np.concatenate([new.nod[mine], old.nod[theirs]]))


def join_time(track: Track, traj: LimbTrajectory, after: float, until: float) -> float | None:
    """Where a window's plan ``traj`` re-joins a queued ``track``: the earliest knot time after ``after`` from
    which, up to ``until`` (s), every knot of either is a knot of both (times within :data:`KNOT_TIME_S`) where
    they agree (positions within :data:`AGREE_M`, velocities within :data:`AGREE_M_S`); None if there is none."""
    lo, hi = np.searchsorted(traj.times, [after, until], side="right")
    if hi <= lo or not len(track):
        return None
    times = traj.times[lo:hi]
    first, last = float(times[0]) - KNOT_TIME_S, float(times[-1]) + KNOT_TIME_S
    knot_times, knot_values, knot_velocities = track.knots(first, last)  # only the queued knots of the span
    a = int(np.searchsorted(knot_times, first, side="left"))
    b = min(int(np.searchsorted(knot_times, last, side="right")) + 1, len(knot_times))
    if b <= a:
        return None
    queued = knot_times[a:b]
    idx = np.minimum(np.searchsorted(queued, times - KNOT_TIME_S), len(queued) - 1)
    shared = np.abs(queued[idx] - times) <= KNOT_TIME_S
    dp = np.abs(knot_values[a:b][idx] - traj.positions[lo:hi]).max(axis=1)
    dv = np.abs(knot_velocities[a:b][idx] - traj.velocities[lo:hi]).max(axis=1)
    bad = np.flatnonzero(~(shared & (dp <= AGREE_M) & (dv <= AGREE_M_S)))
    gaps = np.flatnonzero(np.diff(idx) != 1) + 1  # a queued knot the plan lacks (or the reverse) before these
    start = max(int(bad[-1]) + 1 if bad.size else 0, int(gaps[-1]) if gaps.size else 0)
    return float(times[start]) if start < len(times) else None


def agrees(track: Track, traj: LimbTrajectory, t_s: float, until: float) -> bool:
    """Whether a plan's trajectory ``traj`` agrees with a queued ``track`` from rig time ``t_s`` to ``until`` (s):
    positions within :data:`AGREE_M` and velocities within :data:`AGREE_M_S` at both ends and at every knot of
    either between (both are one cubic on each interval between these times, so agreeing there they agree
    between, within about the same margins). False for an empty track."""
    if not len(track):
        return False
    until = max(until, t_s)
    knot_times, knot_values, knot_velocities = track.knots(t_s, until)
    a = max(int(np.searchsorted(knot_times, t_s, side="right")) - 1, 0)  # the queued knots that shape [t_s, until]
    b = min(int(np.searchsorted(knot_times, until, side="left")) + 1, len(knot_times))
    queued = knot_times[a:b]
    inner = (traj.times > t_s) & (traj.times < until)
    times = np.unique(np.concatenate([[t_s, until], traj.times[inner], queued[(queued > t_s) & (queued < until)]]))
    p1, v1 = hermite(traj.times, traj.positions, traj.velocities, times)
    p2, v2 = hermite(queued, knot_values[a:b], knot_velocities[a:b], times)
    return bool(np.abs(p1 - p2).max() <= AGREE_M and np.abs(v1 - v2).max() <= AGREE_M_S)


@dataclasses.dataclass(frozen=True)
class _Splice:
    """How one limb's trajectory joins its track at the splice time (see :func:`splice_plan`)."""

    p0: np.ndarray
    """The track's position (3,) m at the splice, the first knot queued."""
    v0: np.ndarray
    """... and its velocity (3,) m/s."""
    bridge: list[tuple[float, np.ndarray]]
    """Knots (rig time s, position m, at rest) between the splice and the plan: a brake before a later start."""
    keep: np.ndarray
    """Which of the trajectory's knots are queued, (N,) bool."""
    cut: float
    """Rig time (s) after which the plan's knots and strokes are queued."""


def _splice(traj: LimbTrajectory, t_s: float, p0: np.ndarray, v0: np.ndarray, room: float, blend_s: float,
            brake_s: float) -> _Splice:
    """One limb's splice at rig time ``t_s`` from the track state ``p0``, ``v0``; ``room``: seconds from ``t_s``
    to the limb's first stroke after it."""
    times, pos, vel = traj.times, traj.positions, traj.velocities
    bridge: list[tuple[float, np.ndarray]] = []
    if times[0] > t_s + 1e-6:  # the plan starts later: join its first knot, braking first when there is room
        keep = np.ones(len(times), dtype=bool)
        cut = t_s
        if times[0] - t_s > 2 * brake_s and float(np.linalg.norm(v0)) > 1e-6:
            bridge.append((t_s + brake_s, brake_point(p0, v0, brake_s, 0.0)))
    else:
        p1, v1 = hermite(times, pos, vel, np.array([t_s]))
        agree = float(np.max(np.abs(p1[0] - p0))) <= AGREE_M and float(np.max(np.abs(v1[0] - v0))) <= AGREE_M_S
        cut = t_s + 1e-4 if agree else t_s + min(blend_s, 0.5 * room)
        keep = times > cut
    return _Splice(p0, v0, bridge, keep, cut)


def _append(track: Track, times: np.ndarray, values: np.ndarray, velocities: np.ndarray) -> None:
    """Queue a plan's knots (fresh arrays the caller leaves as they are) after the track's last with
    ``Track.extend``, which keeps them as arrays until sampling reaches them (not copied into the track's lists
    knot by knot, in the physics loop); :class:`TargetError` unless they follow the track's end (and as
    ``extend``: finite, increasing, room)."""
    if times[0] <= track.end_time:
        raise TargetError("plan knot times must increase and follow the splice")
    track.extend(times, values, velocities)


def check_room(scene: DrummerScene, t_s: float, count: int) -> None:
    """Raise :class:`TargetError` (before any track changes) if a limb's track with knots has no room for ``count``
    knots from rig time ``t_s`` seconds on (``Track.check_room``)."""
    for track in scene.limb_tracks.values():
        if len(track):
            track.check_room(t_s, count)


def brake_point(p0: np.ndarray, v0: np.ndarray, brake_s: float, lift: float) -> np.ndarray:
    """Where a limb moving at ``v0`` from ``p0`` stops when braked evenly over ``brake_s`` (never lower), m."""
    p = p0 + v0 * brake_s / 2
    p[2] = max(p[2], p0[2]) + lift
    return p
