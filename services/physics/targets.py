"""Target trajectories streamed ahead of time: knot buffers with cubic Hermite interpolation.

A :class:`Track` holds knots (time s, value (D,), velocity (D,)) and samples
position and velocity at any time (C1 cubic Hermite between knots, the last
knot held with zero velocity after it, the first before it). A new knot at or
before the last one replaces the tail from there (re-planning);
:meth:`Track.replace_span` replaces only the knots of a time span and keeps
those after it (a re-planned window that re-joins the queued plan). Knots older
than the one in use are pruned.

A batch of knots (:meth:`Track.extend`, e.g. a whole gesture plan) is kept as
the batch's own arrays, and its knots are taken into the track's lists only as
sampling comes within one knot of them: copied knot by knot (two small arrays
each), a plan took 0.32 kB a knot, all of it from the start (10 MB per minute
of a Groove beat in a render). The score player's splices take in only the
knots of their window too (:meth:`Track.knots`, :meth:`Track.replace_span`,
which keeps the queued arrays after the window as they are). Reading
``times``, ``values`` or ``velocities`` takes every queued knot into those
lists at once (for callers that read or edit them all, e.g. tests).

A track holds at most ``max_knots`` knots (default :data:`MAX_TRACK_KNOTS`, a
24 h plan of the densest music with margin): a knot, or a batch of knots, that
would pass it is refused with :class:`TargetError` and the knots already queued
stay as they were (a remote sender cannot grow the queue without end).
"""

from __future__ import annotations

import bisect
import math
from typing import Literal

import numpy as np

from common.score.events import MAX_SCORE_SECONDS
from services.physics.kernels import hermite

PLAN_KNOTS_PER_SECOND = 300.0
"""Knots per second of music a track is sized for. The densest gesture plans of the Groove dataset (all 969 files
of a second or more, default kit and planner) queue at most 237 knots per second on one limb between the first and
the last note (a 1.7 s hip-hop fill, right hand) and 216 over a long beat (143 s of frevo, left hand): 300 is a
quarter more than the densest."""
MAX_TRACK_KNOTS = int(PLAN_KNOTS_PER_SECOND * MAX_SCORE_SECONDS)
"""Most knots one track queues: 300 knots/s x 86,400 s (the longest score the reader accepts) = 25,920,000. The most
notes a score may have (500,000) evenly on one hand over 24 h plan at 197 knots/s (17 M knots); denser passages
cost notes faster than they add knots (docs/physics.md, "Bounded queues"). Memory at the bound (measured per knot:
8 bytes from a plan, whose own arrays hold the rest, 0.54 kB streamed one by one, 1.4 kB on the 57-DOF joint track):
0.2 GB, 14 GB, 37 GB."""


class TargetError(ValueError):
    """A target the physics service cannot use: non-finite, wrong length, unreachable, out of limits, past."""


class _Batch:
    """Knots queued as arrays, not taken into a track's lists yet: times (N,) s, values (N, dim), velocities
    (N, dim), the caller's own arrays (not copied); those of ``[first, end)`` are still to take."""

    __slots__ = ("times", "values", "velocities", "first", "end")

    def __init__(self, times: np.ndarray, values: np.ndarray, velocities: np.ndarray) -> None:
        self.times = times
        self.values = values
        self.velocities = velocities
        self.first = 0
        self.end = len(times)

    def __len__(self) -> int:
        return self.end - self.first

    def count_before(self, time: float, side: Literal["left", "right"] = "left") -> int:
        """How many knots still to take are before ``time`` seconds (``side="right"``: at or before it)."""
        return int(np.searchsorted(self.times[self.first:self.end], time, side=side))


class Track:
    """A Hermite-interpolated trajectory of ``dim`` values (see the module docstring)."""

    def __init__(self, dim: int, max_knots: int = MAX_TRACK_KNOTS) -> None:
        self.dim = dim
        self.max_knots = max_knots
        """Most knots queued at once (older ones are pruned as time passes)."""
        self._knot_times: list[float] = []
        self._knot_values: list[np.ndarray] = []
        self._knot_velocities: list[np.ndarray] = []
        self._ahead: _Batch | None = None
        """Knots after those of the lists, not taken into them yet (None: none)."""

    @property
    def times(self) -> list[float]:
        """Every queued knot's time, seconds (all of them taken into the lists: see the module docstring)."""
        self._take_all()
        return self._knot_times

    @times.setter
    def times(self, times: list[float]) -> None:
        self._take_all()
        self._knot_times = times

    @property
    def values(self) -> list[np.ndarray]:
        """Every queued knot's values (dim,), as :attr:`times`."""
        self._take_all()
        return self._knot_values

    @values.setter
    def values(self, values: list[np.ndarray]) -> None:
        self._take_all()
        self._knot_values = values

    @property
    def velocities(self) -> list[np.ndarray]:
        """Every queued knot's velocities (dim,) per second, as :attr:`times`."""
        self._take_all()
        return self._knot_velocities

    @velocities.setter
    def velocities(self, velocities: list[np.ndarray]) -> None:
        self._take_all()
        self._knot_velocities = velocities

    def __len__(self) -> int:
        return len(self._knot_times) + (len(self._ahead) if self._ahead is not None else 0)

    def _take(self, count: int) -> None:
        """Take the next ``count`` knots queued as arrays into the lists (their rows, as :meth:`add` keeps them)."""
        ahead = self._ahead
        assert ahead is not None
        a = ahead.first
        b = min(a + count, ahead.end)
        self._knot_times.extend(ahead.times[a:b].tolist())
        self._knot_values.extend(ahead.values[k] for k in range(a, b))
        self._knot_velocities.extend(ahead.velocities[k] for k in range(a, b))
        ahead.first = b
        if not len(ahead):
            self._ahead = None

    def _take_all(self) -> None:
        if self._ahead is not None:
            self._take(len(self._ahead))

    def _reach(self, t: float) -> None:
        """Take knots into the lists until they hold the first knot after ``t`` seconds, or all of them: what
        sampling at ``t`` needs (the knots before stay until :meth:`prune`)."""
        ahead = self._ahead
        if ahead is None or (self._knot_times and self._knot_times[-1] > t):
            return
        self._take(ahead.count_before(t, side="right") + 1)

    def knots(self, start: float, end: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The queued knots that sampling at times from ``start`` to ``end`` seconds uses: from the last knot at
        or before ``start`` (the first if none is) to the first knot after ``end`` (the last if none is), as
        times (n,) s, values (n, dim) and velocities (n, dim) (copies). Takes in only the knots up to the first
        after ``end``; a plan's later knots stay in its arrays."""
        self._reach(end)
        times = self._knot_times
        a = max(bisect.bisect_right(times, start) - 1, 0)
        b = min(bisect.bisect_right(times, end) + 1, len(times))
        return (np.array(times[a:b], dtype=float), np.array(self._knot_values[a:b], dtype=float).reshape(-1, self.dim),
                np.array(self._knot_velocities[a:b], dtype=float).reshape(-1, self.dim))

    def _count_before(self, time: float) -> int:
        """How many queued knots are before ``time`` seconds."""
        kept = bisect.bisect_left(self._knot_times, time)
        if self._ahead is not None and kept == len(self._knot_times):
            kept += self._ahead.count_before(time)
        return kept

    def _cut(self, time: float) -> None:
        """Drop the knots at and after ``time`` seconds (what a knot there replaces)."""
        ahead = self._ahead
        if ahead is not None and ahead.times[ahead.first] < time:  # every knot of the lists is before it too
            ahead.end = ahead.first + ahead.count_before(time)  # at least its first knot stays
            return
        self._ahead = None
        cut = bisect.bisect_left(self._knot_times, time)
        del self._knot_times[cut:], self._knot_values[cut:], self._knot_velocities[cut:]

    def add(self, time: float, value: np.ndarray, velocity: np.ndarray) -> None:
        """Append a knot (time seconds, value (dim,), velocity (dim,) per second)."""
        v = np.asarray(value, dtype=float).reshape(-1)
        d = np.asarray(velocity, dtype=float).reshape(-1)
        if v.shape != (self.dim,) or d.shape != (self.dim,):
            raise TargetError(f"expected {self.dim} values and {self.dim} velocities, got {v.size} and {d.size}")
        if not (math.isfinite(time) and np.all(np.isfinite(v)) and np.all(np.isfinite(d))):
            raise TargetError("target time, values and velocities must be finite (no NaN or inf)")
        self.check_room(time, 1)
        self._cut(time)
        self._take_all()  # the queued knots before it (all of them, after the cut) go into the lists first
        self._knot_times.append(float(time))
        self._knot_values.append(v)
        self._knot_velocities.append(d)

    def cut(self, time: float) -> None:
        """Drop the knots at and after ``time`` seconds (those a knot there would replace), keeping those before
        (the live core moves a stream's queued knots this way: ``PhysicsCore._retime_streamed``)."""
        self._cut(time)

    def check_room(self, time: float, count: int) -> None:
        """Raise :class:`TargetError` if ``count`` knots from ``time`` seconds on (replacing the knots at and after
        it, as :meth:`add` does) would queue more than ``max_knots``."""
        kept = self._count_before(time)
        if kept + count > self.max_knots:
            raise TargetError(f"target queue full: {kept} knots queued before {time:.4f} s and {count} more would pass "
                              f"the limit of {self.max_knots} knots per track (MAX_TRACK_KNOTS); refused, the queued "
                              "knots are kept")

    def extend(self, times: np.ndarray, values: np.ndarray, velocities: np.ndarray) -> None:
        """Add many knots: times (N,), values (N, dim), velocities (N, dim); all checked before the first is queued
        (a refused batch leaves the track as it was). As :meth:`add` at ``times[0]`` (which a subclass may
        extend) followed by the rest of the knots, which stay in the given arrays (not copied: the caller leaves
        them as they are) until sampling reaches them."""
        t, v, d = self._checked_batch(times, values, velocities)
        if not len(t):
            return
        self.check_room(float(t[0]), len(t))
        self.add(float(t[0]), v[0], d[0])
        if len(t) > 1:
            self._ahead = _Batch(t[1:], v[1:], d[1:])

    def _checked_batch(self, times: np.ndarray, values: np.ndarray, velocities: np.ndarray,
                       non_empty: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A batch of knots as float arrays (N,), (N, dim), (N, dim); :class:`TargetError` unless the times are
        finite and strictly increasing (and some, with ``non_empty``) and every value and velocity finite."""
        t = np.asarray(times, dtype=float)
        v = np.asarray(values, dtype=float)
        d = np.asarray(velocities, dtype=float)
        if t.ndim != 1 or (non_empty and not len(t)) or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
            raise TargetError("knot times must be a finite, strictly increasing" + (", non-empty" if non_empty else "")
                              + " 1-D array")
        if v.shape != (len(t), self.dim) or d.shape != (len(t), self.dim):
            raise TargetError(f"expected ({len(t)}, {self.dim}) values and velocities, got {v.shape} and {d.shape}")
        if not (np.all(np.isfinite(v)) and np.all(np.isfinite(d))):
            raise TargetError("target time, values and velocities must be finite (no NaN or inf)")
        return t, v, d

    def check_span(self, times: np.ndarray, values: np.ndarray, velocities: np.ndarray,
                   until: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Raise :class:`TargetError` if :meth:`replace_span` would refuse these knots (bad batch, not ending before
        ``until`` seconds, or no room for them and the kept tail); else the batch as float arrays."""
        t, v, d = self._checked_batch(times, values, velocities, non_empty=True)
        if not math.isfinite(until):
            raise TargetError("target time, values and velocities must be finite (no NaN or inf)")
        if t[-1] >= until:
            raise TargetError(f"replacement knots must end before {until:.4f} s, the first knot kept")
        self.check_room(float(t[0]), len(t) + len(self) - self._count_before(until))
        return t, v, d

    def replace_span(self, times: np.ndarray, values: np.ndarray, velocities: np.ndarray, until: float) -> None:
        """Replace the knots from ``times[0]`` up to ``until`` seconds (exclusive) by the given ones: times (N,),
        values (N, dim), velocities (N, dim), all before ``until``; the knots before ``times[0]`` and from ``until``
        on stay (a re-plan of a window that re-joins the queued plan). As :meth:`add` at ``times[0]`` (which a
        subclass may extend) followed by the rest of the knots and the kept tail. Everything is checked before
        the track changes: a refused batch leaves it as it was. Only the knots up to the first after ``until``
        are taken into the lists; a plan's knots after it stay in its arrays."""
        t, v, d = self.check_span(times, values, velocities, until)
        self._replace_checked(t, v, d, until)

    def _replace_checked(self, t: np.ndarray, v: np.ndarray, d: np.ndarray, until: float) -> None:
        """:meth:`replace_span` of a span :meth:`check_span` has just passed (as float arrays)."""
        self._reach(until)  # every knot before ``until`` in the lists; the queued arrays after it stay as they are
        ahead, self._ahead = self._ahead, None
        tail = bisect.bisect_left(self._knot_times, until)
        kept_times, kept_values = self._knot_times[tail:], self._knot_values[tail:]
        kept_velocities = self._knot_velocities[tail:]
        self.add(float(t[0]), v[0], d[0])
        self._knot_times.extend(float(x) for x in t[1:])
        self._knot_values.extend(v[1:])
        self._knot_velocities.extend(d[1:])
        self._knot_times.extend(kept_times)
        self._knot_values.extend(kept_values)
        self._knot_velocities.extend(kept_velocities)
        self._ahead = ahead

    def clear(self) -> None:
        self._knot_times.clear()
        self._knot_values.clear()
        self._knot_velocities.clear()
        self._ahead = None

    @property
    def end_time(self) -> float:
        if self._ahead is not None:
            return float(self._ahead.times[self._ahead.end - 1])
        return self._knot_times[-1] if self._knot_times else -math.inf

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Value (dim,) and velocity (dim,) at time ``t`` seconds. Raises ``IndexError`` when empty."""
        self._reach(t)
        times = self._knot_times
        if not times:
            raise IndexError("empty track")
        k = bisect.bisect_right(times, t) - 1
        if k < 0:
            return self._knot_values[0], np.zeros(self.dim)
        if k >= len(times) - 1:
            return self._knot_values[-1], np.zeros(self.dim)
        values, velocities = self._knot_values, self._knot_velocities
        return hermite(t, times[k], times[k + 1], values[k], values[k + 1], velocities[k], velocities[k + 1])

    def prune(self, before: float) -> None:
        """Drop knots no longer needed to sample at times >= ``before``."""
        self._reach(before)
        k = bisect.bisect_right(self._knot_times, before) - 1
        if k > 0:
            del self._knot_times[:k], self._knot_values[:k], self._knot_velocities[:k]
