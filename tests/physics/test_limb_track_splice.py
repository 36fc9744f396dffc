"""``LimbTrack.replace_span``: a window's knots and strikes replace only those of their span.

A live note's window (services/physics/splice.py ``splice_window``) replaces a limb's knots from the splice to its
join time and keeps the queued ones after it; the planned strikes the follow-through uses must go the same way: those
of the span are replaced by the window's, those before it and from the join on stay.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from services.physics.follow_through import LimbTrack, Strike
from services.physics.targets import TargetError

DOWN = np.array([0.0, 0.0, -1.0])


def _strike(t: float) -> Strike:
    return Strike(t, t + 0.002, DOWN, 2.0, "snare")


def _track() -> LimbTrack:
    """Knots every second from 0 to 6 s at z = 0.1 m, strikes at 0.5, 2, 3, 4 and 5.5 s."""
    track = LimbTrack()
    track.extend(np.arange(7.0), np.tile([0.0, 0.0, 0.1], (7, 1)), np.zeros((7, 3)))
    for t in (0.5, 2.0, 3.0, 4.0, 5.5):
        track.add_strike(_strike(t))
    return track


def _span(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return np.linspace(1.5, 3.5, n), np.tile([0.0, 0.0, 0.2], (n, 1)), np.zeros((n, 3))


def test_replace_span_replaces_the_strikes_of_the_span_and_keeps_those_from_until_on() -> None:
    track = _track()
    track.replace_span(*_span(3), until=4.0, strikes=[_strike(1.5), _strike(2.7)])
    assert track.times == [0.0, 1.0, 1.5, 2.5, 3.5, 4.0, 5.0, 6.0]
    assert [s.time for s in track.strikes] == [0.5, 1.5, 2.7, 4.0, 5.5]  # 2 and 3 s replaced; 4 s (until) kept
    # the kept strikes still follow through and are pruned with their knots
    assert track.follow_through(5.505, {}) is not None and track.follow_through(4.003, {}) is not None
    track.prune(5.0)
    assert [s.time for s in track.strikes] == [5.5]


def test_replace_span_without_strikes_drops_only_the_spans() -> None:
    track = _track()
    track.replace_span(*_span(2), until=4.0)
    assert [s.time for s in track.strikes] == [0.5, 4.0, 5.5]


@pytest.mark.parametrize("strikes, until, error", [
    ([_strike(1.0)], 4.0, ValueError),  # before the span's first knot
    ([_strike(4.0)], 4.0, ValueError),  # at until: the queued plan's
    ([_strike(2.7), _strike(2.0)], 4.0, ValueError),  # out of order
    ([_strike(math.nan)], 4.0, ValueError),
    ([_strike(2.0)], 3.0, TargetError),  # a knot at or after until
])
def test_replace_span_refuses_bad_strikes_or_knots_and_leaves_the_strikes_as_they_were(
        strikes: list[Strike], until: float, error: type[Exception]) -> None:
    track = _track()
    with pytest.raises(error):
        track.replace_span(*_span(3), until=until, strikes=strikes)
    assert [s.time for s in track.strikes] == [0.5, 2.0, 3.0, 4.0, 5.5]
    assert track.times == [float(t) for t in range(7)]
