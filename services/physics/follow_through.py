"""Strokes that follow through: a limb whose striker has not met the instrument by the planned bottom keeps going.

The gesture planner ends a stroke at the struck surface: the target reaches
the hit point at the note time, moving into the surface at the stroke's
speed, and turns back within half the contact time (a few millimetres under
the surface; common/gesture/plan.py). A stick tip that lags its target by a
few millimetres (a fast double, a hand braking from a long move) then turns
back above the head and the note is lost; so does a soft kick whose foot
stops the footboard a little early. A drummer throws the stick through the
head, not to it: here, while a limb's striker (its stick, or the beater its
foot drives) has not touched the struck instrument since shortly before the
note, the limb's target at the planned bottom keeps moving into the surface
at the stroke's speed, for at most :data:`FOLLOW_THROUGH_S` and
:data:`FOLLOW_THROUGH_DEPTH_M`; the first touch ends it and the plan's
rebound takes over. A stroke whose striker has touched by the planned bottom
is played exactly as planned. The hi-hat pedal's strokes do not follow
through (its foot presses through to its rest anyway).

:class:`LimbTrack` is a :class:`~services.physics.targets.Track` of a limb's
target that also carries the planned strikes, cut and pruned with its knots.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from common.kit import EventType
from common.score.limbs import HANDS
from services.physics.targets import Track

if TYPE_CHECKING:
    from common.gesture.plan import PlannedStroke

FOLLOW_THROUGH_S = 0.015
"""A stroke keeps going at most this long after its planned bottom, seconds."""
FOLLOW_THROUGH_DEPTH_M = 0.015
"""... and at most this far past the planned bottom, metres."""
TOUCH_LEAD_S = 0.010
"""A touch of the stick up to this long before the note counts as the stroke's (an early contact), seconds."""


class Strike(NamedTuple):
    """A planned contact of a limb's effector (rig seconds, metres, m/s)."""

    time: float
    """Planned first touch, seconds."""
    bottom: float
    """When the planned target is deepest (the note time plus half the contact time), seconds."""
    direction: np.ndarray
    """(3,) unit vector into the surface."""
    speed: float
    """Planned speed into the surface, m/s."""
    instrument: str
    """The kit object struck."""


def follows_through(stroke: PlannedStroke) -> bool:
    """Whether a planned stroke follows through: a stick's, or a bass drum's (the foot presses the footboard
    on until the beater meets the head); not the hi-hat pedal's, whose foot presses through to its rest
    anyway."""
    return stroke.limb in HANDS or stroke.event == EventType.BASS


def strike_of(stroke: PlannedStroke, offset: float) -> Strike:
    """A planned stroke's contact on the rig clock (its plan time plus ``offset`` seconds)."""
    time = stroke.time + offset
    return Strike(time, time + 0.5 * stroke.contact_duration, -np.asarray(stroke.normal, dtype=float),
                  float(stroke.velocity), stroke.object_id)


def _check_strike(strike: Strike) -> None:
    """ValueError unless a strike's time and speed are finite and its speed >= 0."""
    if not (math.isfinite(strike.time) and math.isfinite(strike.speed) and strike.speed >= 0.0):
        raise ValueError("a strike needs a finite time and a finite speed >= 0")


class LimbTrack(Track):
    """A limb's target track (3 values) and its planned strikes, sorted by time."""

    def __init__(self) -> None:
        super().__init__(3)
        self.strikes: list[Strike] = []
        self._times: list[float] = []  # the strikes' times and bottoms, for bisection
        self._bottoms: list[float] = []

    def add(self, time: float, value: np.ndarray, velocity: np.ndarray) -> None:
        """As :meth:`Track.add`; strikes at or after ``time`` seconds go with the knots it replaces."""
        super().add(time, value, velocity)
        if self._times and self._times[-1] >= time:
            self._drop_from(bisect.bisect_left(self._times, time))

    def cut(self, time: float) -> None:
        """As :meth:`Track.cut`; the strikes at or after ``time`` seconds go with the knots."""
        super().cut(time)
        if self._times and self._times[-1] >= time:
            self._drop_from(bisect.bisect_left(self._times, time))

    def replace_span(self, times: np.ndarray, values: np.ndarray, velocities: np.ndarray, until: float,
                     strikes: Sequence[Strike] = ()) -> None:
        """As :meth:`Track.replace_span`; the strikes from ``times[0]`` up to ``until`` seconds go with the knots
        it replaces and ``strikes`` (the span's own, in time order, from ``times[0]`` to before ``until``) take
        their place; the strikes before and from ``until`` on stay. Everything is checked first: a refused call
        leaves the track and its strikes as they were."""
        t, v, d = self.check_span(np.asarray(times, dtype=float).reshape(-1), values, velocities, until)
        for k, strike in enumerate(strikes):
            if not (t[0] <= strike.time < until) or (k and strike.time <= strikes[k - 1].time):
                raise ValueError("a span's strikes must be in time order, from its first knot to before `until`")
            _check_strike(strike)
        kept = bisect.bisect_left(self._times, until)
        tail = self.strikes[kept:], self._times[kept:], self._bottoms[kept:]
        self._replace_checked(t, v, d, until)  # its add at times[0] drops the strikes from there on
        for strike in strikes:
            self.add_strike(strike)
        self.strikes += tail[0]
        self._times += tail[1]
        self._bottoms += tail[2]

    def add_strike(self, strike: Strike) -> None:
        """Mark a planned contact (after the track's strikes so far)."""
        if self._times and strike.time <= self._times[-1]:
            raise ValueError("strikes must be added in time order")
        _check_strike(strike)
        self.strikes.append(strike)
        self._times.append(strike.time)
        self._bottoms.append(strike.bottom)

    def add_strokes(self, strokes: Iterable[PlannedStroke], offset: float, after: float = -math.inf) -> None:
        """Mark the strikes of a plan's strokes that follow through (:func:`follows_through`), those planned
        after ``after`` seconds of the plan, on the rig clock (plan time plus ``offset`` seconds)."""
        for stroke in strokes:
            if stroke.time > after and follows_through(stroke):
                self.add_strike(strike_of(stroke, offset))

    def clear(self) -> None:
        super().clear()
        self._drop_from(0)

    def prune(self, before: float) -> None:
        super().prune(before)
        k = bisect.bisect_left(self._bottoms, before - FOLLOW_THROUGH_S)
        if k:
            del self.strikes[:k], self._times[:k], self._bottoms[:k]

    def _drop_from(self, k: int) -> None:
        del self.strikes[k:], self._times[k:], self._bottoms[k:]

    def follow_through(self, t: float, last_touch: Mapping[str, float]) -> tuple[np.ndarray, np.ndarray] | None:
        """The target (3,) m and velocity (3,) m/s at rig time ``t`` seconds of a stroke still following
        through, or None (sample the track). ``last_touch``: instrument -> when the limb's striker last touched
        it, seconds."""
        for k in range(bisect.bisect_left(self._bottoms, t - FOLLOW_THROUGH_S), len(self.strikes)):
            strike = self.strikes[k]
            if strike.bottom > t:
                return None
            if last_touch.get(strike.instrument, -math.inf) < strike.time - TOUCH_LEAD_S:
                late = t - strike.bottom
                base, _ = self.sample(strike.bottom)
                depth = min(strike.speed * late, FOLLOW_THROUGH_DEPTH_M)
                return base + depth * strike.direction, strike.speed * strike.direction
        return None
