"""Background score plans (the live node's LivePhysicsCore): the loop never runs the planner.

The live node plans ``play``, style and tempo changes and live notes in a worker thread and splices the plan in at
the first step after it is ready; messages still take effect in arrival order. These tests run the node's core in
the OfflineRunner (the in-memory bus, as tests/physics/test_score_player.py) and wait for the worker where a test
needs the plan (``ScorePlayer.wait``), so nothing depends on the machine's speed. Offline cores (``PhysicsCore``)
keep planning in the handler: tests/physics/test_score_player.py.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

import common.gesture.planner as planner_module
from batteur.render import RecorderCore
from common.bus import OfflineRunner
from common.kit import load_kit
from common.messages.score import LiveNote, ScoreLoad, ScoreTransport, TempoScale
from services.interaction.core import InteractionCore
from services.physics.core import PhysicsCore
from services.physics.node import LivePhysicsCore
from tests.waiting import until

SCORES = Path(__file__).parents[1] / "render"
SCORE = SCORES / "short_groove.txt"  # two bars of hi-hat, snare and kick: no toms
HIGH_TOM, SNARE = 48, 38


def _rig(planner: str = "thread", start_s: float = 0.0) -> tuple[PhysicsCore, OfflineRunner, RecorderCore, Any]:
    """The node's core (``planner="offline"``: a plain PhysicsCore) with interaction and a recorder; plans in a
    thread by default, where the tests can hold or watch the planner. ``start_s``: rig time the runner starts at,
    s."""
    kit = load_kit("default")
    settings: dict[str, Any] = {"scene": "drummer", "kit": kit, "grip": "german", "pose_rate_hz": 0, "mode": "live"}
    physics = PhysicsCore(**settings) if planner == "offline" else LivePhysicsCore(planner=planner, **settings)
    assert physics.score_player.wait_loaded(120.0)  # as the node before it listens (play: refused meanwhile)
    physics.score_player.library = [SCORES]
    recorder = RecorderCore()
    runner = OfflineRunner([physics, InteractionCore(kit=kit), recorder], start_s=start_s)
    return physics, runner, recorder, runner.bus.endpoint("control")


def _near(recorder: RecorderCore, instrument: str, t: float, tolerance: float = 0.02) -> list[Any]:
    return [i for i in recorder.impacts.sorted() if i.instrument == instrument and abs(i.time - t) <= tolerance]


@pytest.fixture
def planner_threads(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[bool]]:
    """Records, for every plan, whether the gesture planner ran on the main (the loop's) thread."""
    original = planner_module.plan_gestures
    calls: list[bool] = []

    def recording(*args: Any, **kwargs: Any) -> Any:
        calls.append(threading.current_thread() is threading.main_thread())
        return original(*args, **kwargs)

    monkeypatch.setattr(planner_module, "plan_gestures", recording)
    yield calls


def _send_and_plan(control: Any, player: Any, message: Any) -> None:
    control.send(message, "physics")
    assert player.wait(60.0)


def _settle(runner: OfflineRunner, player: Any) -> None:
    """Step until no plan is in flight and nothing waits (each plan spliced at the step after it is ready)."""
    while player.busy:
        assert player.wait(60.0)
        runner.run_until(runner.now + 0.002)


@pytest.mark.parametrize("planner", ["thread", "process"])
def test_a_live_note_during_a_score_leaves_the_handler_at_once_and_is_played(planner: str,
                                                                              planner_threads: list[bool]) -> None:
    """The node plans in a process of its own (this process's planner is never called); a thread also works."""
    physics, runner, recorder, control = _rig(planner)
    player = physics.score_player
    control.send(ScoreLoad(path=SCORE.name), "physics")
    _send_and_plan(control, player, ScoreTransport(action="play", time=1.5, position=0.0))
    runner.run_until(2.0)
    plans = player.plans
    control.send(LiveNote(time=2.55, pitch=HIGH_TOM, velocity=100, channel=10), "physics")
    assert player.busy and player.plans == plans  # the handler returned with the plan still to splice
    assert player.wait(60.0)
    runner.run_until(2.8)
    physics.close()
    if planner == "thread":
        assert planner_threads and not any(planner_threads)  # every plan (play and the note) off the loop's thread
    else:
        assert planner_threads == []  # every plan in the planning process
    assert player.plans == plans + 1 and physics.rejected == {} and player.late_notes == 0
    assert _near(recorder, "hightom", 2.55), [(i.instrument, round(i.time, 3)) for i in recorder.impacts.sorted()]
    assert _near(recorder, "hihat", 2.7)  # the score goes on


def test_a_stop_right_after_a_live_note_cancels_it_and_the_note_after_the_stop_plays() -> None:
    physics, runner, recorder, control = _rig()
    player = physics.score_player
    runner.run_until(1.0)
    control.send(LiveNote(time=1.4, pitch=HIGH_TOM, velocity=100, channel=10), "physics")
    control.send(ScoreTransport(action="stop", time=0.0, position=0.0), "physics")  # "at once", while it plans
    control.send(LiveNote(time=1.6, pitch=SNARE, velocity=100, channel=10), "physics")  # 0.6 s ahead
    assert player.busy
    _settle(runner, player)  # the note's plan, then the stop, then the snare's plan
    runner.run_until(2.0)
    physics.close()
    # the tom dropped by the stop is counted late and its sender told (until 7 Dec only logged)
    assert physics.rejected == {} and player.late_notes == 1
    assert not [i for i in recorder.impacts.sorted() if i.instrument == "hightom"]  # cancelled by the stop
    assert _near(recorder, "snare", 1.6)


def test_a_live_note_with_just_its_preparation_time_and_no_score_is_played() -> None:
    physics, runner, recorder, control = _rig()
    player = physics.score_player
    runner.run_until(1.0)
    lead = player.preparation_s + 0.01  # 0.278 s: the least the rules ask for, and 10 ms
    _send_and_plan(control, player, LiveNote(time=1.0 + lead, pitch=SNARE, velocity=100, channel=10))
    runner.run_until(1.6)
    physics.close()
    assert player.late_notes == 0 and physics.rejected == {}
    assert _near(recorder, "snare", 1.0 + lead)


def test_a_plan_ready_too_late_counts_its_note_late_and_the_notes_waiting_are_planned_together(
        gate: threading.Event, caplog: pytest.LogCaptureFixture) -> None:
    physics, runner, recorder, control = _rig()
    player = physics.score_player
    runner.run_until(1.0)
    control.send(LiveNote(time=1.35, pitch=HIGH_TOM, velocity=100, channel=10), "physics")  # planned at once
    control.send(LiveNote(time=2.2, pitch=SNARE, velocity=100, channel=10), "physics")  # these two wait
    control.send(LiveNote(time=2.4, pitch=SNARE, velocity=100, channel=10), "physics")
    runner.run_until(1.3)  # the simulation passes the first plan's splice time while it is computed
    plans = player.plans
    with caplog.at_level("WARNING", logger="batteur.physics.score"):
        gate.set()
        _settle(runner, player)
    runner.run_until(2.7)
    physics.close()
    assert player.late_notes == 1 and physics.late >= 1 and physics.rejected == {}
    assert any("planning took" in r.getMessage() for r in caplog.records)  # the log says why
    assert not [i for i in recorder.impacts.sorted() if i.instrument == "hightom"]  # never played late
    assert player.plans == plans + 1  # the two waiting snares: one plan
    assert _near(recorder, "snare", 2.2) and _near(recorder, "snare", 2.4)


def test_a_background_planner_failure_is_counted_as_in_the_handler_and_the_worker_goes_on(
        monkeypatch: pytest.MonkeyPatch) -> None:
    original = planner_module.plan_gestures
    failures = [1]

    def failing_once(*args: Any, **kwargs: Any) -> Any:
        if failures:
            failures.pop()
            raise RuntimeError("planner bug")
        return original(*args, **kwargs)

    monkeypatch.setattr(planner_module, "plan_gestures", failing_once)
    offline, _, _, offline_control = _rig("offline")
    offline_control.send(LiveNote(time=0.5, pitch=SNARE, velocity=100, channel=10), "physics")
    offline.close()
    failures.append(1)
    physics, runner, recorder, control = _rig()
    player = physics.score_player
    _send_and_plan(control, player, LiveNote(time=0.5, pitch=SNARE, velocity=100, channel=10))
    runner.run_until(0.1)
    assert dict(physics.rejected) == dict(offline.rejected) == {"LiveNote": 1}
    assert dict(player.errors) == dict(offline.score_player.errors) == {"LiveNote": 1}
    _send_and_plan(control, player, LiveNote(time=0.6, pitch=SNARE, velocity=100, channel=10))
    runner.run_until(0.9)
    physics.close()
    assert _near(recorder, "snare", 0.6)


def test_closing_the_core_does_not_wait_for_the_plan_in_flight(gate: threading.Event) -> None:
    physics, runner, _, control = _rig()
    player = physics.score_player
    runner.run_until(0.2)
    control.send(LiveNote(time=0.8, pitch=SNARE, velocity=100, channel=10), "physics")
    job = player._job
    assert job is not None
    assert until(job.future.running, 60.0)  # being computed (its worker idle until now: it takes it up at once)
    physics.close()  # the planner is still held: close must return without it
    assert not gate.is_set() and not job.future.done() and not player.busy


def test_the_benchmark_checks_its_options_before_running(capsys: pytest.CaptureFixture[str]) -> None:
    import importlib.util

    spec = importlib.util.spec_from_file_location("bench_live_replan", Path(__file__).parents[2] / "bench" /
                                                  "live_replan.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    with pytest.raises(SystemExit) as stop:
        module.main(["--planner", "fork"])
    assert stop.value.code == 2 and "--planner" in capsys.readouterr().err


def test_targets_sent_right_after_a_live_note_act_after_its_plan(gate: threading.Event) -> None:
    """Every message, not only the score's, waits behind a plan in flight: a hand's waypoint sent after a note is
    queued after the note's gesture (a splice applied later would have cut it out of the track). The planner is
    held until the targets are sent (a loaded machine could otherwise finish the plan before them)."""
    from common.messages.physics import CartesianTarget

    physics, runner, _, control = _rig()
    player = physics.score_player
    runner.run_until(0.5)
    here = physics.scene.current_targets()  # type: ignore[attr-defined]
    control.send(LiveNote(time=0.9, pitch=HIGH_TOM, velocity=100, channel=10), "physics")
    for hand in ("left_hand", "right_hand"):  # whichever hand plays the tom
        x, y, z = (float(v) for v in here[hand])
        control.send(CartesianTarget(limb=hand, time=1.6, x=x, y=y, z=z, vx=0.0, vy=0.0, vz=0.0), "physics")
    assert player.busy
    gate.set()
    _settle(runner, player)
    tracks = physics.scene.limb_tracks  # type: ignore[attr-defined]
    physics.close()
    assert player.plans == 1 and physics.rejected == {}
    assert [tracks[hand].end_time for hand in ("left_hand", "right_hand")] == pytest.approx([1.6, 1.6])


def test_a_tempo_change_planned_in_the_background_re_times_the_rest_of_the_score() -> None:
    from common.score.text import read_score

    physics, runner, recorder, control = _rig()
    player = physics.score_player
    control.send(ScoreLoad(path=SCORE.name), "physics")
    _send_and_plan(control, player, ScoreTransport(action="play", time=1.5, position=0.0))
    runner.run_until(2.0)
    control.send(TempoScale(factor=0.5), "physics")
    assert player.mapping is not None and player.mapping[2] == 1.0  # planning: the old tempo still plays
    _settle(runner, player)
    assert player.mapping is not None
    t_c, p_c, tempo = player.mapping
    assert tempo == 0.5 and t_c >= 2.0 + player.preparation_s  # the change starts once it can be prepared
    runner.run_until(3.9)
    physics.close()
    notes = []
    for e in read_score(SCORE).events:
        t = 1.5 + e.time
        notes.append((t if t < t_c else t_c + (e.time - p_c) / tempo, {"HIHATCLOSED": "hihat", "SNARE": "snare",
                                                                       "BASS": "kick"}[e.event.value]))
    notes = [n for n in notes if n[0] < 3.8]
    assert len(notes) >= 9
    missing = [n for n in notes if not _near(recorder, n[1], n[0], 0.04)]
    assert not missing and physics.rejected == {} and player.late_notes == 0
