"""The live node's score player on a loaded machine, where a plan takes seconds (found by a live-set walkthrough on
one busy core: the planning process got under 1 % of it and a plan took 5-26 s).

A ``stop`` sent at once waited 20 s behind two plans in flight; a ``play`` after slow plans dropped a minute of
music for a planning-time estimate swollen by the slowest plan; a loop asked near a score's end vanished without a
word; a pause after a re-plan was said "before the score started". The planner is held by the ``gate`` fixture (a
plan takes as long as the test wants) or its timing history is the one slow plans leave: nothing here depends on the
machine's speed, and the assertions are on order and outcome, not wall times.
"""

from __future__ import annotations

import logging
import threading
import time
from pathlib import Path
from typing import Any, Literal

import pytest

from batteur.render import RecorderCore
from common.bus import OfflineRunner
from common.kit import load_kit
from common.messages.physics import PhysicsRejected
from common.messages.score import LiveNote, ScoreLoad, ScoreLoop, ScoreTransport, TempoScale
from common.score.text import parse_text
from services.interaction.core import InteractionCore
from services.physics.core import PhysicsCore
from services.physics.node import LivePhysicsCore
from services.physics.plan_worker import PlanWorkers
from services.physics.score_player import (
    PLAN_HISTORY,
    PLAN_MIN_TIMED,
    PLAN_OVERHEAD_S,
    PLAN_SAFETY,
    ScorePlayer,
)
from tests.physics.test_score_loop import FIVE_BARS  # a bar lasts 2 s, 36 notes (20 or more: a per-note time)

LOGGER = "batteur.physics.score"
SENDER = "127.0.0.1:9"
SNARE = 38
FAST_PER_NOTE_S = 0.0004
"""A plan's time per note alone on a core (docs/physics.md: about 0.4 ms)."""
SLOW_PER_NOTE_S = 0.1
"""... on the walkthrough's loaded core (a 439-note plan in 26 s is 0.06 s a note)."""


def _rig(tmp_path: Path, planner: Literal["offline", "thread"] = "thread"
         ) -> tuple[PhysicsCore, OfflineRunner, RecorderCore, Any]:
    """The node's core (``planner="offline"``: a plain PhysicsCore) with interaction and a recorder, five.txt in its
    score library and loaded."""
    (tmp_path / "five.txt").write_text(FIVE_BARS, encoding="utf-8")
    kit = load_kit("default")
    settings: dict[str, Any] = {"scene": "drummer", "kit": kit, "grip": "german", "pose_rate_hz": 0, "mode": "live"}
    physics = PhysicsCore(**settings) if planner == "offline" else LivePhysicsCore(planner=planner, **settings)
    assert physics.score_player.wait_loaded(120.0)
    physics.score_player.library = [tmp_path]
    recorder = RecorderCore()
    runner = OfflineRunner([physics, InteractionCore(kit=kit), recorder])
    control = runner.bus.endpoint("control")
    control.send(ScoreLoad(path="five.txt"), "physics")
    runner.run_until(0.01)
    return physics, runner, recorder, control


def _settle(runner: OfflineRunner, player: ScorePlayer) -> None:
    """Step until no plan is in flight and nothing waits."""
    while player.busy:
        assert player.wait(60.0)
        runner.run_until(runner.now + 0.002)


def _said(caplog: pytest.LogCaptureFixture, words: str) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name == LOGGER and words in r.getMessage()]


def _playing(runner: OfflineRunner, control: Any, player: ScorePlayer, gate: threading.Event) -> None:
    """five.txt plays from rig 1.5 s (its plan let through), then the planner is held again."""
    gate.set()
    control.send(ScoreTransport(action="play", time=1.5, position=0.0), "physics")
    _settle(runner, player)
    gate.clear()
    runner.run_until(3.0)
    assert player.state == "playing" and player.plans == 1


def test_a_stop_at_once_drops_the_re_plan_in_flight_and_a_play_after_it_comes_after_it(
        tmp_path: Path, gate: threading.Event, caplog: pytest.LogCaptureFixture) -> None:
    # the walkthrough: "stop at rig 472.164 s" for a stop sent at ~452, behind two loop re-plans
    physics, runner, recorder, control = _rig(tmp_path)
    player = physics.score_player
    _playing(runner, control, player, gate)
    with caplog.at_level(logging.INFO, logger=LOGGER):
        control.send(TempoScale(factor=0.5), "physics")  # its re-plan held in the planner
        runner.run_until(3.5)
        assert player.busy
        control.send(ScoreTransport(action="stop", time=0.0, position=0.0), "physics")
        # at once, not behind the plan: the play has ended and nothing waits
        assert not player.busy and player.state == "idle" and player.mapping is None
        assert _said(caplog, "acts at once: the tempo re-plan in flight dropped")
        assert _said(caplog, "stop at rig 3.520 s: score 2.020 s")  # where the score was, by the play's clock
        control.send(ScoreTransport(action="play", time=6.0, position=4.0), "physics")  # after the stop: after it
        gate.set()
        _settle(runner, player)
    runner.run_until(6.6)
    physics.close()
    assert physics.rejected == {} and player.late_notes == 0
    assert player.plans == 2  # the play, the play after the stop: the tempo re-plan was never spliced
    assert player.mapping == pytest.approx((6.0, 4.0, 0.5))  # the tempo held back applies to the next play
    hits = recorder.impacts.sorted()
    assert not [i for i in hits if 3.6 <= i.time < 5.9]  # stopped: nothing until the next play
    assert [i for i in hits if i.instrument == "hightom" and abs(i.time - 6.0) <= 0.02]  # bar 3's downbeat, on time


def _refusals(runner: OfflineRunner) -> list[str]:
    """The refusals delivered to the control endpoint from now on (their reasons), filled as they arrive."""
    reasons: list[str] = []
    runner.bus.tap(lambda message, _source, to: reasons.append(message.reason)
                   if isinstance(message, PhysicsRejected) and to == "control" else None)
    return reasons


def test_a_stop_at_once_drops_a_play_in_flight_and_counts_the_waiting_live_notes_late(
        tmp_path: Path, gate: threading.Event, caplog: pytest.LogCaptureFixture) -> None:
    # the stop itself is not refused (it dropped a plan); the live note it dropped was only logged until 7 Dec: now
    # counted late (Health's ``late``) and its sender told, as a note too late to prepare
    physics, runner, recorder, control = _rig(tmp_path)
    player = physics.score_player
    refusals = _refusals(runner)
    with caplog.at_level(logging.INFO, logger=LOGGER):
        control.send(ScoreTransport(action="play", time=1.5, position=0.0), "physics")  # held in the planner
        control.send(LiveNote(time=1.2, pitch=SNARE, velocity=100, channel=10), "physics")  # waits behind it
        control.send(LiveNote(time=1.3, pitch=SNARE, velocity=0, channel=10), "physics")  # a note-off: nothing
        control.send(TempoScale(factor=0.8), "physics")  # waits: keeps its setting for the next play
        runner.run_until(0.5)
        control.send(ScoreTransport(action="stop", time=0.0, position=0.0), "physics")
        assert not player.busy
        assert _said(caplog, "acts at once: the play in flight, 2 waiting live notes dropped")
        gate.set()
        runner.run_until(2.5)
    physics.close()
    # nothing played, and a stop that dropped a plan is not refused for a drummer that never moved
    assert physics.rejected == {} and player.plans == 0 and player.tempo == pytest.approx(0.8)
    assert not recorder.impacts.sorted()
    assert player.late_notes == 1 and physics.late == 1
    assert refusals == ["live note SNARE at 1.200 s arrived at 0.010 s: a stop at rig 0.500 s acted at once and "
                        "dropped it before it was planned; not played"]


def test_a_stop_at_once_counts_the_live_notes_of_the_plan_in_flight_late(
        tmp_path: Path, gate: threading.Event) -> None:
    physics, runner, recorder, control = _rig(tmp_path)
    player = physics.score_player
    _playing(runner, control, player, gate)
    refusals = _refusals(runner)
    control.send(LiveNote(time=4.5, pitch=SNARE, velocity=100, channel=10), "physics")  # its plan held
    runner.run_until(3.2)
    assert player.busy
    control.send(ScoreTransport(action="pause", time=0.0, position=0.0), "physics")
    assert not player.busy and player.state == "paused"
    gate.set()
    runner.run_until(5.0)
    physics.close()
    assert physics.rejected == {} and player.late_notes == 1
    assert len(refusals) == 1 and refusals[0].startswith(
        "live note SNARE at 4.500 s arrived at 3.000 s: a pause at rig 3.2")
    assert not [i for i in recorder.impacts.sorted() if i.instrument == "snare" and abs(i.time - 4.5) < 0.05]


def test_a_stop_sent_ahead_past_the_plan_in_flight_still_waits_its_turn(
        tmp_path: Path, gate: threading.Event) -> None:
    # a play whose notes come before the stop's time must play them: the stop waits behind its plan, as before
    physics, runner, recorder, control = _rig(tmp_path)
    player = physics.score_player
    control.send(ScoreTransport(action="play", time=1.5, position=0.0), "physics")
    control.send(ScoreTransport(action="stop", time=3.0, position=0.0), "physics")
    assert player.busy  # the stop waits behind the play's plan
    gate.set()
    _settle(runner, player)
    runner.run_until(3.5)
    physics.close()
    assert physics.rejected == {} and player.plans == 1
    hits = recorder.impacts.sorted()
    assert [i for i in hits if i.instrument == "hihat" and abs(i.time - 1.5) <= 0.02]
    assert not [i for i in hits if i.time > 3.2]


def test_a_live_note_refused_behind_a_re_plan_says_what_it_waited_behind(
        tmp_path: Path, gate: threading.Event, caplog: pytest.LogCaptureFixture) -> None:
    # "live note SNARE at 391.604 s arrived at 391.452 s, its turn came at 443.890 s": behind what, it did not say
    physics, runner, _, control = _rig(tmp_path)
    player = physics.score_player
    _playing(runner, control, player, gate)
    with caplog.at_level(logging.WARNING, logger=LOGGER):
        control.send(TempoScale(factor=0.9), "physics")  # held
        control.send(LiveNote(time=3.6, pitch=SNARE, velocity=100, channel=10), "physics")  # in order: behind it
        runner.run_until(5.0)  # the planner still held: the note's time passes
        gate.set()
        _settle(runner, player)
    physics.close()
    assert player.late_notes == 1
    said = _said(caplog, "live note SNARE at 3.600 s arrived at 3.000 s, waited ")
    assert said and "s behind a tempo re-plan (its turn came at " in said[0], _said(caplog, "live note")


@pytest.mark.parametrize("slow_plans", [1, PLAN_HISTORY])
def test_a_play_after_slow_plans_drops_no_note_for_its_planning_time(
        tmp_path: Path, caplog: pytest.LogCaptureFixture, slow_plans: int) -> None:
    # "715 notes before 400.694 s cannot be prepared in time; not played": the estimate took the slowest per-note
    # time of the last 8 plans x 1.5 x all notes. One slow plan among 8 no longer counts (the median); when they
    # are all slow the whole score starts later from the asked position, and the log says how late
    physics, runner, recorder, control = _rig(tmp_path)
    player = physics.score_player
    times = [FAST_PER_NOTE_S] * (PLAN_HISTORY - slow_plans) + [SLOW_PER_NOTE_S] * slow_plans
    player._plan_times.extend(times)
    runner.run_until(1.0)
    with caplog.at_level(logging.INFO, logger=LOGGER):
        control.send(ScoreTransport(action="play", time=2.0, position=0.0), "physics")
        _settle(runner, player)
    assert player.mapping is not None
    start = player.mapping[0]
    runner.run_until(start + 0.2)
    physics.close()
    assert player.late_notes == 0 and physics.rejected == {}
    first = [i for i in recorder.impacts.sorted() if i.instrument == "hihat" and abs(i.time - start) <= 0.02]
    assert first  # the score's first note, wherever it starts
    if slow_plans == 1:
        assert start == pytest.approx(2.0)  # on time
    else:
        assert start > 2.0
        said = _said(caplog, "too close to prepare its first note once planned (its plan is expected to take ")
        assert said and f"the whole score starts at {start:.3f} s instead ({start - 2.0:.3f} s late)" in said[0]


@pytest.mark.parametrize("planner", ["offline", "thread"])
def test_a_loop_asked_once_the_play_has_ended_is_said_to_apply_to_the_next_play(
        tmp_path: Path, caplog: pytest.LogCaptureFixture, planner: Literal["offline", "thread"]) -> None:
    # _start_replan ignored a None re-plan (the play ended before it could be laid): the loop vanished silently
    physics, runner, _, control = _rig(tmp_path, planner)
    player = physics.score_player
    control.send(ScoreTransport(action="play", time=1.0, position=6.0), "physics")  # bars 4-5: 4 s
    _settle(runner, player)
    runner.run_until(player.end_time + 0.1)
    with caplog.at_level(logging.INFO, logger=LOGGER):
        control.send(ScoreLoop(first=5, last=5), "physics")
        runner.run_until(runner.now + 0.01)
        _settle(runner, player)
    physics.close()
    assert physics.rejected == {} and player.loop == (5, 5)
    said = _said(caplog, "loop bars 5-5: the play of five.txt ends (its plan at rig ")
    assert said and said[0].endswith("before it could be laid; it applies to the next play")


def test_a_pause_before_a_re_plans_anchor_says_where_the_score_sounds(caplog: pytest.LogCaptureFixture) -> None:
    # "pause at rig 398.495 s, before the score started (from score 100.647 s, ...)" while the play had started at
    # 341: a re-plan's clock starts at its anchor, the planning time ahead; before it the play's clock still sounds
    core = PhysicsCore(scene="drummer", kit=load_kit("default"), grip="german", pose_rate_hz=0)
    player = core.score_player
    player.score = parse_text(FIVE_BARS)
    player.play(1.0, 0.0, 0.5)
    player.tempo = 0.5
    player.replan(3.0)  # from rig 3.02 s; the new clock from its anchor, 3.268 s
    assert player.mapping is not None and player.mapping[0] > 3.1
    with caplog.at_level(logging.INFO, logger=LOGGER):
        player.pause(3.1, 3.0)  # sent ahead, between the re-plan's splice and its anchor
    core.close()
    assert _said(caplog, "pause at") == ["pause at rig 3.100 s: score 2.100 s, bar 2 beat 1.2"]


def test_a_plan_queued_behind_one_a_stop_dropped_is_timed_from_that_ones_end(
        tmp_path: Path, gate: threading.Event, monkeypatch: pytest.MonkeyPatch) -> None:
    # a planning process without a loaded spare is not stopped: the dropped plan finishes unused and the play after
    # the stop waits for it. Its time counted that wait as planning (a 22-note play measured 0.047 s a note, 38
    # times its own), which swelled the next plans' estimate and a plan again's least time
    monkeypatch.setattr(PlanWorkers, "stops_at_once", property(lambda self: False))  # a process, no spare loaded
    physics, runner, _, control = _rig(tmp_path)
    player = physics.score_player
    _playing(runner, control, player, gate)
    control.send(TempoScale(factor=0.5), "physics")  # its re-plan held in the planner
    runner.run_until(3.5)
    control.send(ScoreTransport(action="stop", time=0.0, position=0.0), "physics")  # drops it: it computes on
    control.send(ScoreTransport(action="play", time=6.0, position=4.0), "physics")  # queued behind it
    time.sleep(0.5)  # the dropped plan still held: a wait that is none of the play's planning
    released = time.perf_counter()
    gate.set()
    _settle(runner, player)
    done = time.perf_counter()
    notes = len(player.events)
    physics.close()
    assert physics.rejected == {} and player.plans == 2 and player.mapping == pytest.approx((6.0, 4.0, 0.5))
    # its own planning came after the dropped plan's, which the gate held until ``released``
    assert player._plan_times[-1] * notes <= done - released  # noqa: SLF001


def test_the_planning_estimate_waits_for_enough_timed_plans() -> None:
    # the median of one or two timed plans is one of them: a first plan slowed on a loaded core (here 250 times the
    # usual) made every next plan's estimate, and a play then started seconds late; the default holds until
    # PLAN_MIN_TIMED plans (long or short) have been timed
    core = PhysicsCore(scene="drummer", kit=load_kit("default"), grip="german", pose_rate_hz=0)
    player = core.score_player
    default = player._estimate(100)  # noqa: SLF001
    for _ in range(PLAN_MIN_TIMED - 1):
        player._plan_times.append(SLOW_PER_NOTE_S)  # noqa: SLF001
        player._short_plan_times.append((5, 2.0))  # noqa: SLF001
        assert player._estimate(100) == pytest.approx(default)  # noqa: SLF001
    player._plan_times.append(SLOW_PER_NOTE_S)  # noqa: SLF001
    assert player._estimate(100) == pytest.approx(PLAN_SAFETY * (PLAN_OVERHEAD_S + 100 * SLOW_PER_NOTE_S))  # noqa: SLF001
    player._plan_times.clear()  # noqa: SLF001
    player._short_plan_times.append((5, 2.0))  # noqa: SLF001
    assert player._estimate(100) == pytest.approx(PLAN_SAFETY * 2.0)  # noqa: SLF001
    core.close()
