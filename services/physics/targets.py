"""Target trajectories streamed ahead of time: knot buffers with cubic Hermite interpolation.

A :class:`Track` holds knots (time s, value (D,), velocity (D,)) and samples
position and velocity at any time (C1 cubic Hermite between knots, the last
knot held with zero velocity after it, the first before it). A new knot at or
before the last one replaces the tail from there (re-planning);
:meth:`Track.replace_span` replaces only the knots of a time span and keeps
those after it (a re-planned window that re-joins the queued plan). Knots older
than the one in use are pruned.

A track holds at most ``max_knots`` knots (default :data:`MAX_TRACK_KNOTS`, a
24 h plan of the densest music with margin): a knot, or a batch of knots, that
would pass it is refused with :class:`TargetError` and the knots already queued
stay as they were (a remote sender cannot grow the queue without end).
"""

from __future__ import annotations

import bisect
import math

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
0.32 kB from a plan, 0.54 kB streamed one by one, 1.4 kB on the 57-DOF joint track): 8 GB, 14 GB, 37 GB."""


class TargetError(ValueError):
    """A target the physics service cannot use: non-finite, wrong length, unreachable, out of limits, past."""


class Track:
    """A Hermite-interpolated trajectory of ``dim`` values (see the module docstring)."""

    def __init__(self, dim: int, max_knots: int = MAX_TRACK_KNOTS) -> None:
        self.dim = dim
        self.max_knots = max_knots
        """Most knots queued at once (older ones are pruned as time passes)."""
        self.times: list[float] = []
        self.values: list[np.ndarray] = []
        self.velocities: list[np.ndarray] = []

    def __len__(self) -> int:
        return len(self.times)

    def add(self, time: float, value: np.ndarray, velocity: np.ndarray) -> None:
        """Append a knot (time seconds, value (dim,), velocity (dim,) per second)."""
        v = np.asarray(value, dtype=float).reshape(-1)
        d = np.asarray(velocity, dtype=float).reshape(-1)
        if v.shape != (self.dim,) or d.shape != (self.dim,):
            raise TargetError(f"expected {self.dim} values and {self.dim} velocities, got {v.size} and {d.size}")
        if not (math.isfinite(time) and np.all(np.isfinite(v)) and np.all(np.isfinite(d))):
            raise TargetError("target time, values and velocities must be finite (no NaN or inf)")
        self.check_room(time, 1)
        cut = bisect.bisect_left(self.times, time)
        del self.times[cut:], self.values[cut:], self.velocities[cut:]
        self.times.append(float(time))
        self.values.append(v)
        self.velocities.append(d)

    def check_room(self, time: float, count: int) -> None:
        """Raise :class:`TargetError` if ``count`` knots from ``time`` seconds on (replacing the knots at and after
        it, as :meth:`add` does) would queue more than ``max_knots``."""
        kept = bisect.bisect_left(self.times, time)
        if kept + count > self.max_knots:
            raise TargetError(f"target queue full: {kept} knots queued before {time:.4f} s and {count} more would pass "
                              f"the limit of {self.max_knots} knots per track (MAX_TRACK_KNOTS); refused, the queued "
                              "knots are kept")

    def extend(self, times: np.ndarray, values: np.ndarray, velocities: np.ndarray) -> None:
        """Add many knots: times (N,), values (N, dim), velocities (N, dim); all checked before the first is queued
        (a refused batch leaves the track as it was)."""
        t, v, d = self._checked_batch(times, values, velocities)
        if not len(t):
            return
        self.check_room(float(t[0]), len(t))
        for k in range(len(t)):
            self.add(float(t[k]), v[k], d[k])

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
        self.check_room(float(t[0]), len(t) + len(self.times) - bisect.bisect_left(self.times, until))
        return t, v, d

    def replace_span(self, times: np.ndarray, values: np.ndarray, velocities: np.ndarray, until: float) -> None:
        """Replace the knots from ``times[0]`` up to ``until`` seconds (exclusive) by the given ones: times (N,),
        values (N, dim), velocities (N, dim), all before ``until``; the knots before ``times[0]`` and from ``until``
        on stay (a re-plan of a window that re-joins the queued plan). As :meth:`add` at ``times[0]`` (which a
        subclass may extend) followed by the rest of the knots and the kept tail. Everything is checked before
        the track changes: a refused batch leaves it as it was."""
        t, v, d = self.check_span(times, values, velocities, until)
        tail = bisect.bisect_left(self.times, until)
        kept_times, kept_values = self.times[tail:], self.values[tail:]
        kept_velocities = self.velocities[tail:]
        self.add(float(t[0]), v[0], d[0])
        self.times.extend(float(x) for x in t[1:])
        self.values.extend(v[1:])
        self.velocities.extend(d[1:])
        self.times.extend(kept_times)
        self.values.extend(kept_values)
        self.velocities.extend(kept_velocities)

    def clear(self) -> None:
        self.times.clear()
        self.values.clear()
        self.velocities.clear()

    @property
    def end_time(self) -> float:
        return self.times[-1] if self.times else -math.inf

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Value (dim,) and velocity (dim,) at time ``t`` seconds. Raises ``IndexError`` when empty."""
        if not self.times:
            raise IndexError("empty track")
        k = bisect.bisect_right(self.times, t) - 1
        if k < 0:
            return self.values[0], np.zeros(self.dim)
        if k >= len(self.times) - 1:
            return self.values[-1], np.zeros(self.dim)
        return hermite(t, self.times[k], self.times[k + 1], self.values[k], self.values[k + 1], self.velocities[k],
                       self.velocities[k + 1])

    def prune(self, before: float) -> None:
        """Drop knots no longer needed to sample at times >= ``before``."""
        k = bisect.bisect_right(self.times, before) - 1
        if k > 0:
            del self.times[:k], self.values[:k], self.velocities[:k]
