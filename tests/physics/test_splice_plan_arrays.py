"""A live note's splice takes in only the knots of its window, not the whole rest of a long plan.

A track keeps a plan's knots in the plan's own arrays until sampling reaches them
(tests/physics/test_track_plan_arrays.py). The score player's splices used to read the track's ``times``,
``values`` and ``velocities`` lists and ``Track.replace_span`` took every knot in first: the first live note of a
long score took the whole rest of the plan into the lists at once, in the physics loop (14 ms for 40,000 knots,
0.32 kB a knot). The splices now take in the knots up to the end of their window; they sample exactly as before.
"""

from __future__ import annotations

import copy
from collections.abc import Callable

import numpy as np
import pytest

from common.gesture.plan import GesturePlan, LimbTrajectory
from common.kit import Limb
from common.messages.physics import PhysicsReset
from services.physics.core import PhysicsCore
from services.physics.drummer import DrummerScene
from services.physics.follow_through import LimbTrack
from services.physics.splice import agrees, join_time, splice_plan, splice_window
from services.physics.targets import Track
from tests.physics.test_track_plan_arrays import traced

N = 100_000
"""Knots of the long plan: 17 min of one limb at the densest plans' rate."""
TAKEN_IN_B = 4_000_000
"""More than this is held when the plan's knots are taken in (N x 0.32 kB = 32 MB); the window's own are a few
kB."""


def _knots(n: int, seed: int = 1, start: float = 0.5) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``n`` knots (times s, 10 ms apart on average, values (n, 3), velocities (n, 3))."""
    rng = np.random.default_rng(seed)
    times = start + np.cumsum(rng.uniform(0.002, 0.018, n))
    return times, rng.normal(size=(n, 3)), rng.normal(size=(n, 3))


def _long(make: Callable[[], Track], times: np.ndarray, values: np.ndarray, velocities: np.ndarray,
          taken_in: bool) -> Track:
    """A track of the plan's knots, sampled at its start; ``taken_in``: every knot in its lists (as before)."""
    track = make()
    track.extend(times, values, velocities)
    track.sample(float(times[3]))
    if taken_in:
        assert len(track.times) == len(times)  # reading the lists takes every knot in
    return track


def _assert_same_samples(track: Track, reference: Track, times: np.ndarray) -> None:
    """Both tracks sampled at random times over the whole plan and at every 5th knot, pruned as the drummer prunes:
    the same floats, bit for bit."""
    assert len(track) == len(reference) and track.end_time == reference.end_time
    rng = np.random.default_rng(3)
    queries = np.sort(np.concatenate([rng.uniform(times[0] - 0.5, times[-1] + 0.5, 5000), times[::5]]))
    for t in queries:
        for one in (track, reference):
            one.prune(float(t) - 1.0)
        for got, want in zip(track.sample(float(t)), reference.sample(float(t)), strict=True):
            assert np.array_equal(got, want), t


@pytest.mark.parametrize("make", [lambda: Track(3), LimbTrack], ids=["Track", "LimbTrack"])
def test_replacing_a_span_near_the_start_of_a_long_plan_leaves_the_rest_in_its_arrays(
        make: Callable[[], Track]) -> None:
    times, values, velocities = _knots(N)
    track, reference = (_long(make, times, values, velocities, taken_in) for taken_in in (False, True))
    until = float(times[60])  # a window from knot 20 to knot 60, re-joining the plan there
    span = np.linspace(float(times[20]) + 1e-4, until - 1e-4, 7)
    rng = np.random.default_rng(5)
    new_values, new_velocities = rng.normal(size=(7, 3)), rng.normal(size=(7, 3))

    _, held = traced(lambda: track.replace_span(span, new_values, new_velocities, until))
    assert held < TAKEN_IN_B, held
    reference.replace_span(span, new_values, new_velocities, until)
    _assert_same_samples(track, reference, times)


def test_finding_where_a_window_re_joins_reads_only_the_knots_of_the_window() -> None:
    times, values, velocities = _knots(N)
    track, reference = (_long(LimbTrack, times, values, velocities, taken_in) for taken_in in (False, True))
    window = LimbTrajectory(Limb.LEFT_HAND, times[10:80].copy(), values[10:80].copy(), velocities[10:80].copy())
    window.positions[:20] += 0.01  # the window's plan differs up to its 20th knot, then it is the queued plan's
    after, until = float(times[12]), float(times[75])

    def ask(one: Track) -> tuple[float | None, bool, bool]:
        return (join_time(one, window, after, until), agrees(one, window, float(times[10]), until),
                agrees(one, window, float(times[30]), until))

    found, held = traced(lambda: ask(track))
    assert held < TAKEN_IN_B, held
    assert found == ask(reference) == (float(times[30]), False, True)
    _assert_same_samples(track, reference, times)


@pytest.fixture
def scene(drummer: PhysicsCore) -> DrummerScene:
    drummer.handle(PhysicsReset(time=0.0), 0.0, "test")
    assert isinstance(drummer.scene, DrummerScene)
    return drummer.scene


HANDS = (Limb.LEFT_HAND, Limb.RIGHT_HAND)


def _plan(scene: DrummerScene, times: np.ndarray, lift_m: float) -> GesturePlan:
    """The hands held at rest (``lift_m`` above it) at ``times`` (s)."""
    n, lift = len(times), np.array([0.0, 0.0, lift_m])
    held = {limb: np.repeat((scene.rest_targets[limb.value] + lift)[None, :], n, axis=0) for limb in HANDS}
    trajectories = {limb: LimbTrajectory(limb, times, held[limb], np.zeros((n, 3))) for limb in HANDS}
    return GesturePlan(trajectories=trajectories, strokes=[], start_time=float(times[0]), end_time=float(times[-1]))


def _splices_take_in_only_their_window(scene: DrummerScene, splice: Callable[[], None]) -> None:
    """``splice`` on the scene's hands, each holding a long plan, holds less than the plan taken in, and the tracks
    sample as those the same splice gives on tracks with every knot taken in."""
    tracks = {limb.value: scene.limb_tracks[limb.value] for limb in HANDS}
    references = {name: copy.deepcopy(track) for name, track in tracks.items()}
    for reference in references.values():
        _ = reference.times  # every knot taken in, as the splices did before
    _, held = traced(splice)
    assert held < TAKEN_IN_B, held
    spliced = {name: scene.limb_tracks[name] for name in tracks}
    scene.limb_tracks.update(references)
    try:
        splice()
    finally:
        scene.limb_tracks.update(spliced)
    for name, track in spliced.items():
        knot_times = np.array(copy.deepcopy(track).times)
        _assert_same_samples(track, references[name], knot_times)


def test_a_window_spliced_into_a_long_plan_takes_in_only_its_knots(scene: DrummerScene) -> None:
    times = 0.5 + 0.01 * np.arange(N // 4)
    scene.load_plan(_plan(scene, times, 0.0), 0.5, now=0.0)
    scene.limb_tracks["left_hand"].sample(1.0)
    window = _plan(scene, times[100:300], 0.0)
    window.trajectories[Limb.LEFT_HAND].positions[:100, 2] += 0.02  # a live note's gesture, then the queued plan
    t_s, until = float(times[100]), float(times[290])
    found: list[dict[Limb, float | None]] = []

    def live_note() -> None:  # as the score player: where each hand re-joins its queued plan, then the splice
        joins = {limb: join_time(scene.limb_tracks[limb.value], window.trajectories[limb], t_s + 0.2, until)
                 for limb in HANDS}
        found.append(dict(joins))
        splice_window(scene, window, t_s, {limb: t_j for limb, t_j in joins.items() if t_j is not None}, until)

    _splices_take_in_only_their_window(scene, live_note)
    assert found[0] == found[1] and found[0][Limb.LEFT_HAND] == times[200] and found[0][Limb.RIGHT_HAND] is not None


def test_a_plan_spliced_over_a_long_plan_stays_in_its_arrays(scene: DrummerScene) -> None:
    times = 0.5 + 0.01 * np.arange(N // 4)
    scene.load_plan(_plan(scene, times, 0.0), 0.5, now=0.0)
    scene.limb_tracks["left_hand"].sample(1.0)
    t_s = 1.0  # a re-plan of the whole rest (a tempo change): the hands 2 cm higher from there on
    _splices_take_in_only_their_window(scene, lambda: splice_plan(scene, _plan(scene, times, 0.02), t_s))
