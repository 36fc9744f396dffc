"""A gesture plan's knots stay in the plan's own arrays in physics' target tracks (services/physics/targets.py).

A render loads the whole plan into the drummer's tracks before the first step. Copied knot by knot (two small
arrays a knot), the tracks held 0.32 kB per knot from the start: most of what a render still grew by per second
of music. Now a track keeps a batch of knots as the arrays it was given and takes each knot into its lists only
when sampling comes to it; it samples exactly as one built knot by knot.
"""

from __future__ import annotations

import tracemalloc
from collections.abc import Callable

import numpy as np
import pytest

from common.gesture.plan import GesturePlan, LimbTrajectory
from common.kit import Limb
from common.messages.physics import PhysicsReset
from services.physics.core import PhysicsCore
from services.physics.drummer import DrummerScene
from services.physics.targets import TargetError, Track


def _knots(n: int, seed: int = 1, start: float = 0.5) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``n`` knots (times s, 10 ms apart on average, values (n, 3), velocities (n, 3))."""
    rng = np.random.default_rng(seed)
    times = start + np.cumsum(rng.uniform(0.002, 0.018, n))
    return times, rng.normal(size=(n, 3)), rng.normal(size=(n, 3))


def _one_by_one(times: np.ndarray, values: np.ndarray, velocities: np.ndarray) -> Track:
    track = Track(3)
    for k in range(len(times)):
        track.add(float(times[k]), values[k], velocities[k])
    return track


def traced(work: Callable[[], object]) -> tuple[object, int]:
    """What ``work`` returns and the bytes it left allocated (tracemalloc)."""
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        kept = work()
        return kept, tracemalloc.get_traced_memory()[0] - before
    finally:
        tracemalloc.stop()


def test_a_track_holds_a_plans_knots_without_copying_them() -> None:
    times, values, velocities = _knots(100_000)  # 17 min of one limb at the densest plans' rate
    _one_by_one(times[:2], values[:2], velocities[:2]).sample(float(times[0]))  # numba's first call: not the track's

    def load() -> Track:
        track = Track(3)
        track.extend(times, values, velocities)
        for t in np.arange(0.5, 30.0, 0.001):  # the first 30 s at every step, pruned as the drummer prunes
            track.prune(t - 1.0)
            track.sample(t)
        return track

    track, held = traced(load)
    # copied knot by knot: 100,000 x 0.32 kB = 32 MB; now the lists hold the knots about the time in use
    assert held < 200_000, held
    assert len(track) == len(times) - int(np.searchsorted(times, 29.0, side="right")) + 1


def test_a_track_from_a_batch_samples_as_one_built_knot_by_knot() -> None:
    times, values, velocities = _knots(3000)
    batch, reference = Track(3), _one_by_one(times, values, velocities)
    batch.extend(times, values, velocities)
    assert len(batch) == len(reference) and batch.end_time == reference.end_time
    rng = np.random.default_rng(7)
    queries = np.sort(np.concatenate([rng.uniform(0.0, times[-1] + 1.0, 4000), times[::3]]))
    for t in queries:
        for track in (batch, reference):
            track.prune(t - 0.05)
        for got, want in zip(batch.sample(float(t)), reference.sample(float(t)), strict=True):
            assert np.array_equal(got, want), t  # the same floats, bit for bit
    assert len(batch) == len(reference)


def test_replanning_a_batch_replaces_its_tail_as_before() -> None:
    times, values, velocities = _knots(400)
    batch, reference = Track(3), _one_by_one(times, values, velocities)
    batch.extend(times, values, velocities)
    batch.sample(float(times[10]))
    cut = float(times[200]) - 1e-3  # a new knot inside the queued arrays: the knots from there are replaced
    for track in (batch, reference):
        track.add(cut, np.ones(3), np.zeros(3))
    assert batch.times == reference.times and batch.end_time == cut
    assert all(np.array_equal(a, b) for a, b in zip(batch.values, reference.values, strict=True))
    # a batch after knots: it replaces them from its first knot; the room is counted over every knot queued
    more = Track(3, max_knots=500)
    more.extend(times, values, velocities)
    more.extend(times[300:] + 0.5, values[300:], velocities[300:])
    assert len(more) == int(np.searchsorted(times, times[300] + 0.5)) + 100
    with pytest.raises(TargetError, match="target queue full"):
        more.extend(times + 10.0, values, 2 * velocities)  # 400 more after the 450 or so queued: no room
    assert len(more) == int(np.searchsorted(times, times[300] + 0.5)) + 100  # refused: kept as it was
    room = more.max_knots - len(more)
    more.check_room(float(times[-1]) + 1.0, room)  # the knots still in the arrays count as queued
    with pytest.raises(TargetError, match="target queue full"):
        more.check_room(float(times[-1]) + 1.0, room + 1)


@pytest.fixture
def scene(drummer: PhysicsCore) -> DrummerScene:
    drummer.handle(PhysicsReset(time=0.0), 0.0, "test")
    assert isinstance(drummer.scene, DrummerScene)
    return drummer.scene


def test_the_drummer_loads_a_long_plan_without_copying_it(scene: DrummerScene) -> None:
    n = 50_000  # per limb: 8 minutes of the densest plans
    trajectories = {}
    for name in ("left_hand", "right_hand", "left_foot", "right_foot"):
        times = 0.5 + 0.01 * np.arange(n)
        positions = np.repeat(scene.rest_targets[name][None, :], n, axis=0)
        trajectories[Limb(name)] = LimbTrajectory(Limb(name), times, positions, np.zeros((n, 3)))
    plan = GesturePlan(trajectories=trajectories, strokes=[], start_time=0.5, end_time=0.5 + 0.01 * (n - 1))
    _, held = traced(lambda: scene.load_plan(plan, 0.5, now=0.0))
    # copied knot by knot: 4 x 50,000 x 0.32 kB = 64 MB; now the rig times of the knots (8 bytes each) and a few
    assert held < 4 * n * 8 + 500_000, held
    assert all(len(track) == n + 2 for name, track in scene.limb_tracks.items() if name.endswith("hand"))
    target, _ = scene.cartesian_targets(0.75)["left_hand"]
    assert np.allclose(target - scene.target_offset["left_hand"], scene.rest_targets["left_hand"], atol=0.06)
