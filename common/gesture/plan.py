"""Gesture plan data types: what the physics service tracks.

A :class:`GesturePlan` holds, per limb, a Cartesian trajectory of the limb's
effector (a :class:`LimbTrajectory`):

* ``left_hand`` / ``right_hand``: the stick tip of the stick held in that hand;
* ``left_foot`` / ``right_foot``: the ball of the foot on the pedal footboard
  (the pedal end the beater is driven from).

Trajectories are knot sequences (times, positions, velocities) interpolated
with cubic Hermite splines, so a sampled trajectory is continuous in position
and velocity (C1) and reproduces the knot velocities exactly. All positions are
world metres (z up, drummer at the origin facing +y, +x to the drummer's
right), velocities metres per second, times seconds on the score clock (the
first note of the score is not necessarily at 0; the plan starts at
``start_time``).

A stroke's contact is the knot at ``PlannedStroke.time``: the effector reaches
``PlannedStroke.target`` moving into the surface at ``PlannedStroke.velocity``
(m/s along ``-normal``); the velocity then reverses over
``PlannedStroke.contact_duration`` seconds to the rebound velocity
(``elasticity * velocity`` along ``+normal``), without a jump.

The plan also carries a head target (a world point to look at, and a nod
angle) and the per-note feasibility issues found while planning.
"""

from __future__ import annotations

import bisect
import dataclasses
import enum
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from common.kit import EventType, Limb


class LimbSample(NamedTuple):
    """One limb's effector state at a time: position (3,) metres, velocity (3,) m/s."""

    position: np.ndarray
    velocity: np.ndarray


def hermite(
    times: np.ndarray, positions: np.ndarray, velocities: np.ndarray, t: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Cubic Hermite interpolation of knots at query times ``t`` (M,), clamped at the ends.

    Returns positions (M, D) and velocities (M, D). Outside the knot range the
    first/last position is held with zero velocity.
    """
    n = len(times)
    t = np.asarray(t, dtype=float)
    if n == 1:
        pos = np.repeat(positions[:1], len(t), axis=0)
        return pos, np.zeros_like(pos)
    idx = np.clip(np.searchsorted(times, t, side="right") - 1, 0, n - 2)
    t0 = times[idx]
    h = times[idx + 1] - t0
    s = np.clip((t - t0) / h, 0.0, 1.0)[:, None]
    p0, p1 = positions[idx], positions[idx + 1]
    m0, m1 = velocities[idx] * h[:, None], velocities[idx + 1] * h[:, None]
    s2, s3 = s * s, s * s * s
    pos = (2 * s3 - 3 * s2 + 1) * p0 + (s3 - 2 * s2 + s) * m0 + (-2 * s3 + 3 * s2) * p1 + (s3 - s2) * m1
    dpos = (6 * s2 - 6 * s) * p0 + (3 * s2 - 4 * s + 1) * m0 + (-6 * s2 + 6 * s) * p1 + (3 * s2 - 2 * s) * m1
    vel = dpos / h[:, None]
    outside = (t < times[0]) | (t > times[-1])
    if np.any(outside):
        vel[outside] = 0.0
        pos[t < times[0]] = positions[0]
        pos[t > times[-1]] = positions[-1]
    return pos, vel


@dataclass(frozen=True)
class LimbTrajectory:
    """Cartesian effector trajectory of one limb (stick tip or foot).

    Parameters
    ----------
    limb : Limb
        Which limb. Hands: the tip of the stick held in that hand. Feet: the
        ball of the foot on the pedal footboard.
    times : np.ndarray, shape (N,)
        Knot times, seconds, strictly increasing.
    positions : np.ndarray, shape (N, 3)
        Knot positions, world metres.
    velocities : np.ndarray, shape (N, 3)
        Knot velocities, metres per second.
    """

    limb: Limb
    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray

    def __post_init__(self) -> None:
        times = np.asarray(self.times, dtype=float)
        positions = np.asarray(self.positions, dtype=float)
        velocities = np.asarray(self.velocities, dtype=float)
        if times.ndim != 1 or len(times) == 0:
            raise ValueError("times must be a non-empty 1-D array")
        if positions.shape != (len(times), 3) or velocities.shape != (len(times), 3):
            raise ValueError(f"positions and velocities must have shape ({len(times)}, 3)")
        if not np.all(np.isfinite(times)):  # a NaN compares False and would pass the order check
            raise ValueError("times must be finite")
        if np.any(np.diff(times) <= 0):
            raise ValueError("times must be strictly increasing")
        if not (np.all(np.isfinite(positions)) and np.all(np.isfinite(velocities))):
            raise ValueError("positions and velocities must be finite")
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "positions", positions)
        object.__setattr__(self, "velocities", velocities)

    @property
    def start_time(self) -> float:
        return float(self.times[0])

    @property
    def end_time(self) -> float:
        return float(self.times[-1])

    def sample(self, t: float) -> LimbSample:
        """Position (3,) metres and velocity (3,) m/s at time ``t`` seconds (held outside the range).

        Scalar fast path (a few microseconds) for physics loops; same result as :meth:`sample_many`.
        """
        cache = self.__dict__.get("_lists")
        if cache is None:  # plain-float copies for this scalar path, made on first use
            cache = (self.times.tolist(), self.positions.tolist(), self.velocities.tolist())
            object.__setattr__(self, "_lists", cache)
        times: list[float] = cache[0]
        ps: list[list[float]] = cache[1]
        vs: list[list[float]] = cache[2]
        n = len(times)
        if n == 1 or t <= times[0] or t >= times[-1]:
            k = 0 if (n == 1 or t <= times[0]) else n - 1
            inside = n > 1 and t == times[k]
            return LimbSample(np.array(ps[k]), np.array(vs[k]) if inside else np.zeros(3))
        i = bisect.bisect_right(times, t) - 1
        t0 = times[i]
        h = times[i + 1] - t0
        u = (t - t0) / h
        u2, u3 = u * u, u * u * u
        a, b, c, d = 2 * u3 - 3 * u2 + 1, (u3 - 2 * u2 + u) * h, -2 * u3 + 3 * u2, (u3 - u2) * h
        da, db, dc, dd = (6 * u2 - 6 * u) / h, 3 * u2 - 4 * u + 1, (-6 * u2 + 6 * u) / h, 3 * u2 - 2 * u
        p0, p1, m0, m1 = ps[i], ps[i + 1], vs[i], vs[i + 1]
        pos = [a * p0[k] + b * m0[k] + c * p1[k] + d * m1[k] for k in range(3)]
        vel = [da * p0[k] + db * m0[k] + dc * p1[k] + dd * m1[k] for k in range(3)]
        return LimbSample(np.array(pos), np.array(vel))

    def sample_many(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Positions (M, 3) and velocities (M, 3) at times ``t`` (M,) seconds."""
        return hermite(self.times, self.positions, self.velocities, np.asarray(t, dtype=float))

    def resample(self, rate_hz: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Uniformly resampled trajectory: times (M,), positions (M, 3), velocities (M, 3)."""
        t = np.arange(self.times[0], self.times[-1] + 0.5 / rate_hz, 1.0 / rate_hz)
        pos, vel = self.sample_many(t)
        return t, pos, vel


HEAD_WINDOW_KNOTS = 256
"""Knots of a head trajectory :meth:`HeadTrajectory.sample` copies as plain floats at a time (5 s at the planner's
50 Hz): refilled once per 255 knots on physics' increasing times (after a jump, two knots until sampling walks on)."""
_NO_WINDOW: tuple[int, list[float], list[list[float]]] = (0, [], [])


@dataclass(frozen=True)
class HeadTrajectory:
    """Where the head looks and how it nods.

    Parameters
    ----------
    times : np.ndarray, shape (N,)
        Seconds, strictly increasing.
    targets : np.ndarray, shape (N, 3)
        World point (metres) the head turns toward (follows the active hand).
    nod : np.ndarray, shape (N,)
        Head pitch offset, radians (positive: chin down), peaking on each beat.
    """

    times: np.ndarray
    targets: np.ndarray
    nod: np.ndarray

    def sample(self, t: float) -> tuple[np.ndarray, float]:
        """Look-at point (3,) metres and nod angle (radians) at time ``t``, linearly interpolated (held before the
        first knot and after the last).

        The same numbers as ``np.interp`` on each column (its formula, in the same order), found by one binary
        search: the physics asks at every 1 ms step, and ``np.interp`` on a column copies the whole column. The
        search runs over plain-float copies of at most :data:`HEAD_WINDOW_KNOTS` knots about the last time asked
        for, refilled when ``t`` leaves them (a copy of every knot grew with the piece: 0.68 MB a minute).
        """
        start, times, rows = self.__dict__.get("_window", _NO_WINDOW)  # first knot's index, times, x y z nod rows
        if times and times[0] <= t < times[-1]:
            i = bisect.bisect_right(times, t) - 1  # times[i] <= t < times[i + 1]
        else:
            j = int(np.searchsorted(self.times, t, side="right")) - 1  # bisect_right over every knot
            if j < 0:
                return self.targets[0].copy(), float(self.nod[0])
            if j >= len(self.times) - 1:
                return self.targets[j].copy(), float(self.nod[j])
            # walking on (physics' steps): the knots ahead; a jump (a reset, random order): the two about ``t``,
            # and the knots ahead once sampling walks on from there (a full copy at every jump cost 20 times more)
            walking = start <= j < start + len(times) + HEAD_WINDOW_KNOTS
            start, times, rows = self._window_from(j, HEAD_WINDOW_KNOTS if walking else 2)
            i = 0
        x0 = times[i]
        if x0 == t:
            return self.targets[start + i].copy(), float(self.nod[start + i])
        x1 = times[i + 1]
        out = [(y1 - y0) / (x1 - x0) * (t - x0) + y0 for y0, y1 in zip(rows[i], rows[i + 1], strict=True)]
        return np.array(out[:3]), out[3]

    def _window_from(self, j: int, knots: int) -> tuple[int, list[float], list[list[float]]]:
        """Plain-float copies (bisect and indexing on lists, not array scalars) of ``knots`` knots from ``j`` on,
        kept for the next calls: one tuple, replaced whole, so a call never sees half of a refill."""
        end = min(j + knots, len(self.times))
        rows = [[*row, nod] for row, nod in zip(self.targets[j:end].tolist(), self.nod[j:end].tolist(), strict=True)]
        window = (j, self.times[j:end].tolist(), rows)
        object.__setattr__(self, "_window", window)
        return window

    @property
    def cached_knots(self) -> int:
        """Knots :meth:`sample` holds as plain floats now (at most :data:`HEAD_WINDOW_KNOTS`, whatever the length)."""
        return len(self.__dict__.get("_window", _NO_WINDOW)[1])


class Grip(enum.StrEnum):
    """Stick grips of the 2009 gesture database."""

    FRENCH = "french"
    GERMAN = "german"


def planned_grip(hands: str) -> Grip:
    """The grip gestures are planned with for hands holding ``hands``: that grip where the gesture database has it
    (french, german), else german (american, traditional: no captured units). ``batteur render`` and the physics
    node's score player both plan by it."""
    return Grip(hands) if hands in (g.value for g in Grip) else Grip.GERMAN


class Nuance(enum.StrEnum):
    """Playing nuances of the 2009 gesture database."""

    LEGATO = "legato"
    TENUTO = "tenuto"
    ACCENT = "accent"
    VERTICAL_ACCENT = "vertical_accent"
    STACCATO = "staccato"


@dataclass(frozen=True)
class PlannedStroke:
    """One planned contact.

    Parameters
    ----------
    time : float
        Contact time (first touch), seconds; the note's onset.
    limb : Limb
        Limb playing it.
    event : EventType
        Drum event type.
    object_id : str
        Kit object struck (the sounding object; for BASS the kick drum).
    hit_point : np.ndarray, shape (3,)
        Where the sounding object is struck, world metres (by a hand that is not the event's preferred one, at
        the event's ``off_hand`` point).
    target : np.ndarray, shape (3,)
        Where the limb's effector is at contact, world metres: ``hit_point``
        for hands; the pedal footboard for feet.
    normal : np.ndarray, shape (3,)
        Unit surface normal at ``target`` (the effector approaches along ``-normal``).
    velocity : float
        Effector speed into the surface at contact, m/s.
    note_velocity : float
        Score velocity in [0, 1].
    note_index : int
        Index of the note in the score's event list.
    zone, r, theta : str, float, float
        Hit zone, radius r/a and angle (radians) on the object of the point struck (``hit_point``).
    lift : float
        Preparatory height above the target before the stroke, metres.
    rebound_velocity : float
        Effector speed away from the surface after contact, m/s.
    contact_duration : float
        Planned contact time, seconds (3-6 ms for sticks).
    grip, nuance : Grip, Nuance
        Gesture unit family used.
    rebound_double : bool
        True when this stroke is the bounce of a rebound double: the second note
        of one hand's wrist stroke, played on the rebound with the fingers sooner
        than the event's minTimeGap, from a low ``lift`` (docs/gestures.md).
    """

    time: float
    limb: Limb
    event: EventType
    object_id: str
    hit_point: np.ndarray
    target: np.ndarray
    normal: np.ndarray
    velocity: float
    note_velocity: float
    note_index: int
    zone: str = "centre"
    r: float = 0.0
    theta: float = 0.0
    lift: float = 0.0
    rebound_velocity: float = 0.0
    contact_duration: float = 0.004
    grip: Grip = Grip.GERMAN
    nuance: Nuance = Nuance.TENUTO
    rebound_double: bool = False


class IssueReason(enum.StrEnum):
    """Why a note could not be played as written."""

    TOO_FAST = "too_fast"  # same limb faster than the kit's minTimeGap (and not a rebound double)
    TOO_MANY_HANDS = "too_many_hands"  # more than two hand events at once
    HIHAT_CONFLICT = "hihat_conflict"  # two hi-hat events at the same time
    LIMB_BUSY = "limb_busy"  # a foot event while that foot is already playing
    CROSSING = "crossing"  # arms cross to reach the combination
    UNREACHABLE = "unreachable"  # target outside the limb's reach
    UNKNOWN_NOTE = "unknown_note"  # MIDI pitch with no drum event
    DUPLICATE = "duplicate"  # double event removed


class IssueAction(enum.StrEnum):
    """What the planner did with a problematic note."""

    DROPPED = "dropped"
    MOVED_TO_OTHER_HAND = "moved_to_other_hand"
    SUBSTITUTED_PEDAL = "substituted_pedal"
    MOVED_TO_OTHER_FOOT = "moved_to_other_foot"
    PLAYED_ANYWAY = "played_anyway"  # kept as written, physics may miss it
    MERGED = "merged"


@dataclass(frozen=True)
class FeasibilityIssue:
    """A note beyond human limits and what the plan did with it.

    ``note_index`` indexes the score's event list; ``time`` is in seconds.
    """

    note_index: int
    time: float
    event: EventType | None
    reason: IssueReason
    action: IssueAction
    detail: str = ""


@dataclass
class GesturePlan:
    """Everything the physics tracks for one score.

    Parameters
    ----------
    trajectories : dict[Limb, LimbTrajectory]
        Effector trajectory per limb (stick tips, feet). Every limb of the kit
        is present, idle limbs hold a rest position.
    strokes : list[PlannedStroke]
        All planned contacts, sorted by time.
    issues : list[FeasibilityIssue]
        Notes that could not be played as written, and what was done.
    head : HeadTrajectory | None
        Head look-at target and nod.
    start_time, end_time : float
        Seconds; the plan covers [start_time, end_time].
    kit_name : str
        Name of the kit the plan was made for.
    mode : str
        ``"gesture"`` (database units, co-articulated) or ``"keyframe"`` (2001 baseline).
    cymbal_swings : list[CymbalSwing]
        Keyframe mode: cymbal swing after each cymbal stroke (empty in gesture mode;
        physics simulates the swing).
    """

    trajectories: dict[Limb, LimbTrajectory]
    strokes: list[PlannedStroke]
    issues: list[FeasibilityIssue] = field(default_factory=list)
    head: HeadTrajectory | None = None
    start_time: float = 0.0
    end_time: float = 0.0
    kit_name: str = ""
    mode: str = "gesture"
    cymbal_swings: list[CymbalSwing] = field(default_factory=list)

    def sample(self, t: float) -> dict[Limb, LimbSample]:
        """Per-limb effector position (3,) metres and velocity (3,) m/s at time ``t`` seconds."""
        return {limb: traj.sample(t) for limb, traj in self.trajectories.items()}

    def strokes_of(self, limb: Limb) -> list[PlannedStroke]:
        """The strokes one limb plays, in time order."""
        return [s for s in self.strokes if s.limb == limb]

    def from_time(self, t: float) -> GesturePlan:
        """The plan from time ``t`` (seconds) on: each limb's knots at or after ``t`` (a limb with none keeps its
        last knot, where it ends) and the strokes from ``t``; ``start_time`` stays, so rig times map as before.

        A performer joining at ``t`` moves from wherever it is to each limb's first remaining knot.
        """
        trajectories = {}
        for limb, traj in self.trajectories.items():
            first = min(int(np.searchsorted(traj.times, t, side="left")), len(traj.times) - 1)
            trajectories[limb] = LimbTrajectory(limb, traj.times[first:], traj.positions[first:],
                                                traj.velocities[first:])
        return dataclasses.replace(self, trajectories=trajectories,
                                   strokes=[s for s in self.strokes if s.time >= t],
                                   cymbal_swings=[c for c in self.cymbal_swings if c.time >= t])

    def next_stroke(self, limb: Limb, t: float) -> PlannedStroke | None:
        """The first stroke of ``limb`` at or after time ``t``, or None."""
        for s in self.strokes:
            if s.limb == limb and s.time >= t:
                return s
        return None


@dataclass(frozen=True)
class CymbalSwing:
    """Keyframe-mode cymbal swing after a stroke (Kragtwijk et al. 2001).

    angle(t) = eta ** (t - time) * alpha_max * sin(beta * (t - time)), radians,
    about the horizontal axis perpendicular to the stroke direction.
    """

    object_id: str
    time: float
    alpha_max: float
    eta: float
    beta: float
    axis: np.ndarray

    def angle(self, t: float | np.ndarray) -> np.ndarray:
        """Swing angle (radians) at time(s) ``t`` seconds; zero before the stroke."""
        dt = np.asarray(t, dtype=float) - self.time
        out = np.power(self.eta, np.maximum(dt, 0.0)) * self.alpha_max * np.sin(self.beta * np.maximum(dt, 0.0))
        return np.where(dt >= 0, out, 0.0)
