"""A live note during a score re-plans a window around it, not the rest of the performance.

The 55 s Groove file plays in the OfflineRunner (tests/physics/test_score_player.py's rig); a live note mid-score
is planned with the notes from ``CONTEXT_S`` before the splice to a little after it, and its knots replace the
queued ones only until each limb re-joins its queued plan. The tracks must be those a re-plan of the whole rest of
the performance gives (``whole``: what every live note did before), sampled every millisecond to the end, and the
note must sound. ``Track.replace_span`` is the track operation behind it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from common.messages.score import LiveNote, ScoreLoad, ScoreTransport
from services.physics import score_player as score_player_module
from services.physics.drummer import DrummerScene
from services.physics.node import LivePhysicsCore
from services.physics.score_player import ScorePlayer
from services.physics.targets import TargetError, Track
from tests.physics.test_live_replan import _rig as _live_rig
from tests.physics.test_score_player import MIDI, _rig

NOTE_AT_S = 4.05
"""Rig time the live note is sent: 3 s into the 55 s score (which starts at 1 s)."""
LEAD_S = 0.4
"""The live note sounds this long after it is sent, s (its preparation time is 0.268 s): at 4.45 s, where a hand
and the bass foot are free (169 ms and more from their strokes; the planner would drop a note between strokes
closer than an instrument's minTimeGap)."""
AGREE_M = 1e-6
AGREE_M_S = 1e-6
"""Window and whole re-plan tracks agree within these (measured at every 1 ms sample for the three notes below: at
most 3.5e-18 m and 0 m/s, float rounding where the splice knot splits a queued segment)."""
INSTRUMENT = {49: "crash", 36: "kick", 46: "hihat"}
TOLERANCE_S = {49: 0.005, 36: 0.010, 46: 0.005}
"""The note's impact within this of its time: sticks 5 ms; the kick 10 ms (it lands 6 ms early, as with the whole
re-plan; the score's kicks are checked within 40 ms in test_score_player.py)."""


def offline_playing(from_s: float = 0.0) -> tuple[Any, Any, Any, Any]:
    """A PhysicsCore (plans in the handler) with the 55 s groove asked to play from rig time 1 s:
    (physics, runner, recorder, control endpoint). ``from_s``: the rig starts at this time, s, and the score plays
    from its position ``from_s`` at rig time ``1 + from_s`` (a later note's rig time as when played from the start,
    without simulating the drummer through the score before it)."""
    physics, runner, recorder, control = _rig(start_s=from_s)
    physics.score_player.library = [MIDI.parent]
    control.send(ScoreLoad(path=MIDI.name), "physics")
    runner.run_until(from_s + 0.2)
    control.send(ScoreTransport(action="play", time=1.0 + from_s, position=from_s), "physics")
    return physics, runner, recorder, control


def live_playing(from_s: float = 0.0) -> tuple[LivePhysicsCore, Any, Any, Any]:
    """The live node's core (plans in a thread) with the 55 s groove playing from rig time 1 s, its plan spliced:
    (physics, runner, recorder, control endpoint). ``from_s``: as :func:`offline_playing`'s."""
    physics, runner, recorder, control = _live_rig("thread", start_s=from_s)
    assert isinstance(physics, LivePhysicsCore)
    physics.score_player.library = [MIDI.parent]
    control.send(ScoreLoad(path=MIDI.name), "physics")
    control.send(ScoreTransport(action="play", time=1.0 + from_s, position=from_s), "physics")
    assert physics.score_player.wait(60.0)
    return physics, runner, recorder, control


def _whole(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every live note re-planned with the whole rest of the performance (the behaviour before the window)."""
    monkeypatch.setattr(ScorePlayer, "_window_end", lambda self, new, t_s, widen=False: math.inf)


@pytest.fixture(scope="module")
def whole_replans() -> Callable[[int], dict[str, Any]]:
    """``_play(pitch)`` with every live note re-planned with the whole rest (``_whole``): the reference tracks,
    computed once per pitch in the module. The crash's is the reference of two tests, which only read it."""
    done: dict[int, dict[str, Any]] = {}

    def whole(pitch: int) -> dict[str, Any]:
        if pitch not in done:
            with pytest.MonkeyPatch.context() as patch:
                _whole(patch)
                core, _, _, done[pitch] = _play(pitch)
                core.close()
        return done[pitch]

    return whole


def _scene(physics: Any) -> DrummerScene:
    assert isinstance(physics.scene, DrummerScene)
    return physics.scene


def _play(pitch: int, until: float | None = None) -> tuple[Any, Any, Any, dict[str, Any]]:
    """Play the score, send the live note at NOTE_AT_S; returns the core, runner, recorder and what the tracks
    hold right after the note's plan (knots, strikes) with the performance's notes."""
    physics, runner, recorder, control = offline_playing()
    player = physics.score_player
    runner.run_until(NOTE_AT_S)
    control.send(LiveNote(time=NOTE_AT_S + LEAD_S, pitch=pitch, velocity=100, channel=10), "physics")
    queued = {name: (list(track.times), [v.copy() for v in track.values], [v.copy() for v in track.velocities],
                     [(s.time, s.bottom, s.instrument, s.speed) for s in track.strikes])
              for name, track in _scene(physics).limb_tracks.items()}
    state = {"tracks": queued, "events": [(e.time, e.event, e.limb) for e in player.events],
             "plan_notes": len(player.last_plan.strokes) if player.last_plan else 0, "status": player.status()}
    if until is not None:
        runner.run_until(until)
    return physics, runner, recorder, state


def _samples(knots: tuple[list[float], list[np.ndarray], list[np.ndarray], Any], times: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
    track = Track(3)
    track.times, track.values, track.velocities = knots[0], knots[1], knots[2]
    sampled = [track.sample(float(t)) for t in times]
    return np.array([p for p, _ in sampled]), np.array([v for _, v in sampled])


def _assert_same_tracks(window: dict[str, Any], whole: dict[str, Any]) -> None:
    """Every limb's track sampled every 1 ms from the splice to the end of the performance, and its strikes."""
    for name, knots in whole["tracks"].items():
        mine = window["tracks"][name]
        times = np.arange(NOTE_AT_S, max(knots[0][-1], mine[0][-1]) + 0.1, 0.001)
        (p1, v1), (p2, v2) = _samples(mine, times), _samples(knots, times)
        dp, dv = np.abs(p1 - p2).max(axis=1), np.abs(v1 - v2).max(axis=1)
        k = int(np.argmax(dp))
        assert dp.max() <= AGREE_M and dv.max() <= AGREE_M_S, f"{name}: {dp.max():.2e} m at {times[k]:.3f} s"
        assert mine[3] == knots[3], name  # the strikes the follow-through uses
    assert window["events"] == whole["events"]  # every note with the hand a whole re-plan gives it


@pytest.mark.parametrize("pitch", [49, 36, 46])
def test_a_live_note_mid_score_re_plans_a_window_and_the_tracks_are_the_whole_re_plans(
        pitch: int, whole_replans: Callable[[int], dict[str, Any]]) -> None:
    """A crash (a hand), a kick (the bass foot) and an open hi-hat (a hand, and the pedal lifts)."""
    physics, _, recorder, window = _play(pitch, until=NOTE_AT_S + LEAD_S + 0.3)
    physics.close()
    assert window["status"]["live_window_misses"] == 0 and window["status"]["late_notes"] == 0
    assert physics.rejected == {}
    assert window["plan_notes"] < len(window["events"]) / 4  # a window of the 438 notes left, not all of them
    t = NOTE_AT_S + LEAD_S
    near = [i for i in recorder.impacts.sorted()
            if i.instrument == INSTRUMENT[pitch] and abs(i.time - t) <= TOLERANCE_S[pitch]]
    assert near, f"no {INSTRUMENT[pitch]} impact within {TOLERANCE_S[pitch]} s of {t:.3f} s"
    whole = whole_replans(pitch)
    assert whole["plan_notes"] >= len(whole["events"]) - 1  # the reference re-planned everything
    _assert_same_tracks(window, whole)


def test_a_window_that_cannot_re_join_falls_back_to_the_whole_re_plan_and_plays(
        monkeypatch: pytest.MonkeyPatch, whole_replans: Callable[[int], dict[str, Any]]) -> None:
    """No knot of the window's plan re-joins the queued plan: the note is planned with the whole rest."""
    monkeypatch.setattr(score_player_module, "join_time", lambda *args: None)
    physics, _, recorder, fallback = _play(49, until=NOTE_AT_S + LEAD_S + 0.3)
    physics.close()
    assert fallback["status"]["live_window_misses"] == 1 and fallback["status"]["plans"] == 2  # play, the note
    assert physics.rejected == {} and fallback["status"]["late_notes"] == 0
    t = NOTE_AT_S + LEAD_S
    assert [i for i in recorder.impacts.sorted() if i.instrument == "crash" and abs(i.time - t) <= 0.005]
    monkeypatch.undo()
    _assert_same_tracks(fallback, whole_replans(49))


@pytest.mark.parametrize("joins", [True, False])
def test_a_background_live_note_plans_its_window_or_else_the_whole_rest_and_is_played(
        joins: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    """The live node: the window's plan is spliced; or, when it does not re-join, the note is planned again with
    the whole rest (given 1 s of lead, so the second plan has time)."""
    if not joins:
        monkeypatch.setattr(score_player_module, "join_time", lambda *args: None)
    physics, runner, recorder, control = live_playing()
    player = physics.score_player
    t = NOTE_AT_S + LEAD_S
    runner.run_until(t - 1.0)
    plans = player.plans
    control.send(LiveNote(time=t, pitch=49, velocity=100, channel=10), "physics")
    while player.busy:  # the window's plan (then the whole one), each spliced at the step after it is ready
        assert player.wait(60.0)
        runner.run_until(runner.now + 0.002)
    runner.run_until(t + 0.3)
    physics.close()
    assert player.window_misses == (0 if joins else 1) and player.plans == plans + 1 and player.late_notes == 0
    assert physics.rejected == {}
    assert player.last_plan is not None
    assert (len(player.last_plan.strokes) < len(player.events) / 4) == joins
    assert [i for i in recorder.impacts.sorted() if i.instrument == "crash" and abs(i.time - t) <= 0.005]


def test_replace_span_replaces_only_the_knots_of_the_span() -> None:
    track = Track(1)
    track.extend(np.arange(6.0), np.arange(6.0)[:, None], np.zeros((6, 1)))
    track.replace_span(np.array([1.5, 2.5]), np.array([[10.0], [11.0]]), np.ones((2, 1)), until=4.0)
    assert track.times == [0.0, 1.0, 1.5, 2.5, 4.0, 5.0]
    assert [float(v[0]) for v in track.values] == [0.0, 1.0, 10.0, 11.0, 4.0, 5.0]
    assert [float(v[0]) for v in track.velocities] == [0.0, 0.0, 1.0, 1.0, 0.0, 0.0]


@pytest.mark.parametrize("times, values, until, why", [
    ([2.0, 1.5], [[1.0], [2.0]], 4.0, "increasing"),
    ([1.5, 4.0], [[1.0], [2.0]], 4.0, "end before"),
    ([1.5, 2.5], [[1.0], [math.nan]], 4.0, "finite"),
    ([1.5, 2.5], [[1.0], [2.0]], math.inf, "finite"),
    ([], [], 4.0, "non-empty"),
])
def test_replace_span_refuses_a_bad_batch_and_leaves_the_track_as_it_was(times: list[float],
                                                                         values: list[list[float]], until: float,
                                                                         why: str) -> None:
    track = Track(1)
    track.extend(np.arange(6.0), np.arange(6.0)[:, None], np.zeros((6, 1)))
    with pytest.raises(TargetError, match=why):
        track.replace_span(np.array(times), np.array(values).reshape(-1, 1), np.zeros((len(times), 1)), until)
    assert track.times == [0.0, 1.0, 2.0, 3.0, 4.0, 5.0] and [float(v[0]) for v in track.values] == track.times


def test_replace_span_counts_the_kept_tail_against_the_track_bound() -> None:
    track = Track(1, max_knots=8)
    track.extend(np.arange(6.0), np.arange(6.0)[:, None], np.zeros((6, 1)))
    # 2 knots before 1.5 s and 2 kept from 4 s: 3 new fit (7), 6 do not (10)
    with pytest.raises(TargetError, match="queue full"):
        track.replace_span(np.linspace(1.5, 3.5, 6), np.zeros((6, 1)), np.zeros((6, 1)), until=4.0)
    assert track.times == [0.0, 1.0, 2.0, 3.0, 4.0, 5.0]
    track.replace_span(np.linspace(1.5, 3.5, 3), np.zeros((3, 1)), np.zeros((3, 1)), until=4.0)
    assert len(track) == 7 and track.times[-2:] == [4.0, 5.0]
