"""The physics node's start and its planning worker: the node says it is up only once the worker has loaded the
planner, only one planning process starts until the first plan is done, and a live note sent while the worker
still loads is refused at once, with the reason, instead of planned late.

Before: the node listened (its "listening on" line, its Health answers to the rig's Hellos) while two planning
processes still loaded at once; under a load of 20 the first plan took 15-36 s and the notes sent meanwhile waited
and were refused as late.

A thread worker stands in for the process where the test needs its load held: ``load_planner`` is its first task
(a process loads the same way, its first task run in it), and a test can make it wait.
"""

from __future__ import annotations

import argparse
import logging
import multiprocessing
import os
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

import common.gesture.planner as planner_module
from common.messages.physics import PhysicsRejected
from common.messages.score import LiveNote, ScoreTransport, TempoScale
from services.physics import node as node_module
from services.physics import plan_worker
from services.physics.node import LivePhysicsCore, PhysicsNodeSettings, make_core
from services.physics.plan_worker import PLANNER_NICE, PlanWorkers

SENDER = "127.0.0.1:9"
SNARE = 38
SCORE = Path(__file__).parents[1] / "render" / "short_groove.txt"


@pytest.fixture
def held_load(monkeypatch: pytest.MonkeyPatch) -> Iterator[threading.Event]:
    """A thread worker's load waits until the returned event is set (set after 300 s at the latest, so a test that
    waited for it fails instead of hanging)."""
    release = threading.Event()

    def load() -> None:
        release.wait(300.0)

    monkeypatch.setattr(plan_worker, "load_planner", load)
    try:
        yield release
    finally:
        release.set()


def test_the_node_is_made_and_listens_only_once_its_planner_is_loaded(
        monkeypatch: pytest.MonkeyPatch, held_load: threading.Event, caplog: pytest.LogCaptureFixture) -> None:
    """``make_core`` returns (and so the node listens: says it is up, answers Hellos) only once its planning
    worker has loaded. The held load ends only when someone waits for it: a node that did not wait returned with
    its worker still loading."""
    monkeypatch.setattr(node_module, "PlanWorkers", lambda kind: PlanWorkers("thread"))
    wait_loaded = PlanWorkers.wait_loaded

    def waited(self: PlanWorkers, timeout_s: float | None = None) -> bool:
        held_load.set()  # a load slower than the scene: it ends only while the node waits for it
        return wait_loaded(self, timeout_s)

    monkeypatch.setattr(PlanWorkers, "wait_loaded", waited)
    with caplog.at_level(logging.INFO, logger="batteur.physics"):
        core = make_core(PhysicsNodeSettings(discovery=False, pose_rate_hz=0), argparse.Namespace())
    try:
        assert isinstance(core, LivePhysicsCore)
        assert not core.score_player.loading
        assert any(r.getMessage().startswith("planning process ready") for r in caplog.records)
    finally:
        core.close()


def test_a_planner_that_does_not_load_in_time_does_not_keep_the_node_down(
        monkeypatch: pytest.MonkeyPatch, held_load: threading.Event, caplog: pytest.LogCaptureFixture) -> None:
    """Past ``PLANNER_LOAD_WAIT_S`` the node starts anyway and says why (its live notes are refused until the load
    is done: the test above)."""
    monkeypatch.setattr(node_module, "PlanWorkers", lambda kind: PlanWorkers("thread"))
    monkeypatch.setattr(node_module, "PLANNER_LOAD_WAIT_S", 0.01)
    with caplog.at_level(logging.INFO, logger="batteur.physics"):
        core = make_core(PhysicsNodeSettings(discovery=False, pose_rate_hz=0), argparse.Namespace())
    try:
        assert core.score_player.loading  # held until the end of the test
        assert any("has not loaded the planner" in r.getMessage() and r.levelno == logging.WARNING
                   for r in caplog.records)
    finally:
        core.close()


def _planners(before: set[int]) -> set[int]:
    return {p.pid for p in multiprocessing.active_children() if p.pid is not None} - before


def test_one_planning_process_until_the_first_plan_is_done() -> None:
    """The spare starts only once a plan has been computed: at start the two loaded together and shared the CPU
    with the node's own start. The first loads at the node's priority, then lowers its own."""
    before = _planners(set())
    workers = PlanWorkers("process")
    try:
        assert workers.wait_loaded(120.0) and not workers.loading
        (first,) = _planners(before)
        assert os.getpriority(os.PRIO_PROCESS, first) == os.getpriority(os.PRIO_PROCESS, 0) + PLANNER_NICE
        workers.idle()  # no plan computed yet: still one
        assert _planners(before) == {first}
        assert workers.submit(int).result(120.0) == 0
        workers.idle()  # the first plan is done: the spare starts
        assert len(_planners(before)) == 2
    finally:
        workers.close()


def test_a_live_note_while_the_planner_loads_is_refused_at_once_with_the_reason(
        held_load: threading.Event) -> None:
    """Planned after the load it would be late (seconds); it was planned late, its sender told only then. A note
    after the load is planned as always."""
    core = LivePhysicsCore(planner="thread", scene="drummer", grip="german", pose_rate_hz=0, mode="live")
    player = core.score_player
    try:
        assert player.loading
        core.step(1.0)
        out = core.handle(LiveNote(time=2.0, pitch=SNARE, velocity=100, channel=10), 1.0, SENDER)
        replies: list[Any] = [(o.to, o.message) for o in out if isinstance(o.message, PhysicsRejected)]
        assert [(to, message.address) for to, message in replies] == [(SENDER, LiveNote.ADDRESS)]
        reason = replies[0][1].reason
        assert "still loading the planner" in reason and "not played" in reason, reason
        assert player.late_notes == 1 and not player.busy and core.rejected == {}
        held_load.set()
        assert player.wait_loaded(60.0) and not player.loading
        out = core.handle(LiveNote(time=2.5, pitch=SNARE, velocity=100, channel=10), 1.1, SENDER)
        assert not [o for o in out if isinstance(o.message, PhysicsRejected)]
        assert player.busy and player.late_notes == 1  # planned
        assert player.wait(60.0)
    finally:
        core.close()


def _refusals(out: list[Any]) -> list[tuple[str, str, str]]:
    """The refusals among a core's output: (to, address, reason)."""
    return [(o.to, o.message.address, o.message.reason) for o in out if isinstance(o.message, PhysicsRejected)]


def test_a_play_while_the_planner_loads_is_refused_at_once_with_the_reason(held_load: threading.Event) -> None:
    """It waited for the load (seconds), the score then starting that late and every message after it (a stop)
    waiting behind it, its sender told nothing. Refused at once, counted; a play after the load is planned."""
    core = LivePhysicsCore(planner="thread", scene="drummer", grip="german", pose_rate_hz=0, mode="live")
    player = core.score_player
    try:
        player.load(SCORE, trusted=True)
        assert player.loading
        core.step(1.0)
        out = core.handle(ScoreTransport(action="play", time=2.0, position=0.0), 1.0, SENDER)
        ((to, address, reason),) = _refusals(out)
        assert (to, address) == (SENDER, ScoreTransport.ADDRESS)
        assert "still loading the planner" in reason and "not played" in reason, reason
        assert not player.busy and core.rejected == {"ScoreTransport": 1}  # Health's dropped_other
        assert player.state != "playing"
        held_load.set()
        assert player.wait_loaded(60.0) and not player.loading
        out = core.handle(ScoreTransport(action="play", time=2.5, position=0.0), 1.1, SENDER)
        assert _refusals(out) == []
        assert player.busy  # planned
        assert player.wait(60.0)
    finally:
        core.close()


def test_a_tempo_change_while_the_planner_loads_applies_at_once_or_is_refused_if_a_score_plays(
        held_load: threading.Event) -> None:
    """Nothing playing, a tempo (or style) change has nothing to plan: applied at once, as always. A score playing
    (``--play-at`` plans in the node, the worker may still load), its re-plan would wait for the load and every
    message after it behind that: refused at once with the reason, the tempo unchanged."""
    core = LivePhysicsCore(planner="thread", scene="drummer", grip="german", pose_rate_hz=0, mode="live")
    player = core.score_player
    try:
        player.load(SCORE, trusted=True)
        assert player.loading
        core.step(1.0)
        assert _refusals(core.handle(TempoScale(factor=1.5), 1.0, SENDER)) == []
        assert player.tempo == 1.5 and not player.busy
        player.play(2.0, 0.0, 1.0)  # what the node's --play-at does, in its set-up: planned here
        assert player.state == "playing"
        out = core.handle(TempoScale(factor=0.5), 1.1, SENDER)
        ((to, address, reason),) = _refusals(out)
        assert (to, address) == (SENDER, TempoScale.ADDRESS)
        assert "still loading the planner" in reason and "not applied" in reason, reason
        assert player.tempo == 1.5 and not player.busy and core.rejected == {"TempoScale": 1}
    finally:
        core.close()


def test_a_live_note_whose_turn_comes_while_a_new_worker_loads_is_refused_with_the_reason(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """A divergence during the first plan (no spare yet) starts a new worker, which loads; a live note that waited
    behind the dropped plan is refused at its turn, not planned late."""
    held = [threading.Event(), threading.Event()]
    held[0].set()  # the first worker loads at once, the one after the divergence is held
    loads = list(held)  # each load takes its event from here; `held` keeps them all to release at the end (a load
    # left waiting held the interpreter's exit 5 minutes: concurrent.futures joins its threads)
    planning, release = threading.Event(), threading.Event()

    def load() -> None:
        if loads:
            loads.pop(0).wait(300.0)

    def held_plan(*args: Any, **kwargs: Any) -> Any:
        planning.set()
        release.wait(300.0)
        raise RuntimeError("never used: its plan was dropped")

    monkeypatch.setattr(plan_worker, "load_planner", load)
    monkeypatch.setattr(planner_module, "plan_gestures", held_plan)
    core = LivePhysicsCore(planner="thread", scene="drummer", grip="german", pose_rate_hz=0, mode="live")
    player = core.score_player
    try:
        assert player.wait_loaded(60.0)
        core.step(1.0)
        assert core.handle(LiveNote(time=2.0, pitch=SNARE, velocity=100, channel=10), 1.0, SENDER) == []
        assert core.handle(LiveNote(time=2.2, pitch=SNARE, velocity=100, channel=10), 1.0, SENDER) == []
        assert planning.wait(60.0) and player.busy  # the first note's plan is computed, the second waits
        player.reset()  # what a divergence does: the plan in flight dropped, its worker replaced
        assert player.loading
        out = core.step(1.001)
        replies = [o.message.reason for o in out if isinstance(o.message, PhysicsRejected) and o.to == SENDER]
        assert len(replies) == 1 and "still loading the planner" in replies[0], replies
        assert player.late_notes == 1 and not player.busy
    finally:
        for event in [*held, release]:
            event.set()
        core.close()


BREAK_DATABASE = """import os, sys
if os.environ.get("BATTEUR_TEST_BREAK_PLANNER"):
    sys.modules["common.gesture.database"] = None  # its import fails: a broken installation, in the child only
"""


def test_a_planning_process_whose_load_fails_gives_way_to_a_thread(tmp_path: Any,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """A process whose load raised stayed up and failed every plan with the same error (its pool not broken, so no
    fallback), while the node said 'planning process ready'; it now stops, and the plans go to a thread."""
    (tmp_path / "sitecustomize.py").write_text(BREAK_DATABASE)  # run at the spawned child's start
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(tmp_path), os.environ.get("PYTHONPATH", "")]))
    monkeypatch.setenv("BATTEUR_TEST_BREAK_PLANNER", "1")
    workers = PlanWorkers("process")
    try:
        assert workers.wait_loaded(120.0)
        assert workers.load_error is not None  # the process stopped: its pool broken
        assert workers.submit(os.getpid).result(60.0) == os.getpid()  # planned in a thread of this process
        assert workers.kind == "thread"
    finally:
        workers.close()
