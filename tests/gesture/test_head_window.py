"""The head trajectory's sampling holds a bounded window of knots, not the whole piece (common/gesture/plan.py).

Physics asks ``HeadTrajectory.sample`` for the look-at point at every 1 ms step. Its plain-float copy of every knot
(made on first use) grew with the piece, 0.68 MB a minute: most of what a render still grew by with its length.
Now it copies a window of knots, refilled as sampling moves, and gives the same floats as ``np.interp``.
"""

from __future__ import annotations

import tracemalloc

import numpy as np

from common.gesture.plan import HEAD_WINDOW_KNOTS, HeadTrajectory

RATE_HZ = 50.0
"""The planner's head rate (PlannerConfig.head_rate)."""


def _head(minutes: float, seed: int = 5) -> HeadTrajectory:
    """A head trajectory as the planner makes them: knots every 20 ms from 0.5 s, random targets and nods."""
    rng = np.random.default_rng(seed)
    times = np.arange(0.5, 0.5 + minutes * 60.0, 1.0 / RATE_HZ)
    return HeadTrajectory(times, rng.normal(size=(len(times), 3)), rng.normal(size=len(times)))


def _interp(head: HeadTrajectory, t: float) -> tuple[list[float], float]:
    return [float(np.interp(t, head.times, head.targets[:, k])) for k in range(3)], float(np.interp(t, head.times,
                                                                                                    head.nod))


def _assert_as_interp(head: HeadTrajectory, queries: np.ndarray) -> None:
    for t in queries:
        target, nod = head.sample(float(t))
        want_target, want_nod = _interp(head, float(t))
        assert target.tolist() == want_target and nod == want_nod, t  # the same bits


def test_head_samples_are_np_interps_in_any_order() -> None:
    head = _head(2.0)  # 6,000 knots: many windows
    rng = np.random.default_rng(11)
    times = head.times
    anywhere = rng.uniform(times[0] - 1.0, times[-1] + 1.0, 1500)  # random order: a jump at almost every call
    knots = rng.choice(times, 300)  # exactly on knots, the first and last among them
    _assert_as_interp(head, np.concatenate([anywhere, knots, times[[0, -1]], [times[0] - 5.0, times[-1] + 5.0]]))


def test_head_samples_are_np_interps_forward_with_jumps_back() -> None:
    head = _head(1.0)
    times = head.times
    # physics' steps from before the first knot, and on every knot (a window ends on one)
    forward = np.sort(np.concatenate([np.arange(0.0, 25.0, 0.001), times[times < 25.0]]))
    back = np.arange(3.0, 9.0, 0.001)  # a reset: earlier times sampled again
    tail = np.arange(times[-1] - 6.0, times[-1] + 0.5, 0.001)  # past the last knot: held
    _assert_as_interp(head, np.concatenate([forward, back, forward[forward > 20.0], [0.7, 24.0], tail]))


def _held_after_playing(head: HeadTrajectory) -> tuple[int, int]:
    """The most knots cached at once and the bytes left allocated (tracemalloc) by sampling ``head`` at increasing
    times, 10 ms apart, from its start to past its end."""
    most = 0
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        for t in np.arange(head.times[0], head.times[-1] + 1.0, 0.01).tolist():
            head.sample(t)
            most = max(most, head.cached_knots)
        return most, tracemalloc.get_traced_memory()[0] - before
    finally:
        tracemalloc.stop()


def test_head_sampling_holds_the_same_few_knots_for_a_long_piece() -> None:
    short_knots, short_bytes = _held_after_playing(_head(1.0))
    long_knots, long_bytes = _held_after_playing(_head(10.0))
    assert short_knots == long_knots == HEAD_WINDOW_KNOTS  # was: every knot, 3,000 a minute
    # was: 0.68 MB a minute (6.8 MB for 10 minutes); now a window's lists, the same bound for both
    assert short_bytes < 100_000 and long_bytes < 100_000, (short_bytes, long_bytes)
