"""A ``play`` the physics node can no longer meet plays the score from its first note, later, rather than losing it.

A physics node up only after its ``--play-at`` time (``batteur rig --score`` on a loaded machine) plans it in its
set-up, before its loop's first step, which came 0.6 s later on a loaded machine; a play already past started 0.5 s
after the set-up, so the first note was due before the simulation started and was lost (a weak hi-hat, no kick). It
now starts with the whole lead-in an on-time play has. A time too close for the first note (a node up just before
it, asked ``whole``; a background plan ready too late for its time) moves the whole score the same way instead of
leaving the first notes out.
"""

from __future__ import annotations

import threading
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

from batteur.render import RecorderCore
from common.bus import OfflineRunner
from common.kit import load_kit
from common.messages.score import ScoreLoad, ScoreTransport
from common.score.text import read_score
from services.interaction.core import InteractionCore
from services.physics.core import PhysicsCore
from services.physics.node import LivePhysicsCore, PhysicsNodeSettings, start_score

SCORE = Path(__file__).parents[1] / "render" / "short_groove.txt"
INSTRUMENT = {"HIHATCLOSED": "hihat", "SNARE": "snare", "BASS": "kick"}
SET_UP_S = 15.6
"""Rig time of the node's set-up (the score's play), seconds: --play-at 0.2 long past."""
FIRST_STEP_S = 16.2
"""Rig time of its loop's first step, where the simulation starts (0.6 s later, as seen on a loaded machine)."""
HEARD_BY_S = 0.5
"""A set-up play is simulated this long past the score's start: its first note, checked within 20 ms of the start,
has been struck and heard by then (the rest of the 2.1 s score is not what these tests check; its lateness is
counted when the play is planned)."""


def first_note_missed(recorder: RecorderCore, score_start: float) -> list[str]:
    """The instruments of the score's first note not heard within 20 ms of ``score_start`` (rig s): none, if played."""
    heard = {i.instrument for i in recorder.impacts.sorted() if abs(i.time - score_start) <= 0.02}
    return [INSTRUMENT[e.event.value] for e in read_score(SCORE).events
            if e.time == 0.0 and INSTRUMENT[e.event.value] not in heard]


def set_up_play(at: float, now: float, caplog: pytest.LogCaptureFixture) -> tuple[PhysicsCore, RecorderCore, float]:
    """A live drummer core played by the node's set-up (``start_score``) with ``--play-at`` ``at``, at rig time
    ``now``, before any step; its simulation starts at :data:`FIRST_STEP_S` and runs :data:`HEARD_BY_S` past the
    score's start. (core, impacts, the score's start)."""
    kit = load_kit("default")
    physics = PhysicsCore(scene="drummer", kit=kit, grip="german", pose_rate_hz=0, mode="live")
    player = physics.score_player
    player.load(SCORE, trusted=True)
    node: Any = SimpleNamespace(settings=PhysicsNodeSettings(score=str(SCORE), play_at=at), core=physics,
                                clock=SimpleNamespace(now=lambda: now))
    with caplog.at_level("INFO", logger="batteur.physics.score"):  # a start-up play's lateness is INFO
        start_score(node)
    assert player.mapping is not None
    start = player.mapping[0]
    recorder = RecorderCore()
    runner = OfflineRunner([physics, InteractionCore(kit=kit), recorder], start_s=max(FIRST_STEP_S, now))
    runner.run_until(start + HEARD_BY_S)
    physics.close()
    return physics, recorder, start


def test_a_play_already_past_in_the_set_up_plays_the_first_note(caplog: pytest.LogCaptureFixture) -> None:
    physics, recorder, start = set_up_play(0.2, SET_UP_S, caplog)
    assert any("already past" in r.getMessage() for r in caplog.records)  # said, with how late
    assert physics.score_player.late_notes == 0
    assert first_note_missed(recorder, start) == []  # the kick was not heard at all


def test_a_set_up_play_too_close_for_its_first_note_moves_the_whole_score(caplog: pytest.LogCaptureFixture) -> None:
    # a node up 0.3 s before its --play-at: the notes of the first 0.2 s were left out ("cannot be prepared in time")
    physics, recorder, start = set_up_play(FIRST_STEP_S + 0.3, FIRST_STEP_S, caplog)
    assert physics.score_player.late_notes == 0
    assert start > FIRST_STEP_S + 0.3  # later, as a whole
    assert any("too close to prepare its first note" in r.getMessage() for r in caplog.records)
    assert first_note_missed(recorder, start) == []


def test_a_play_planned_too_late_for_its_first_note_moves_the_whole_score(
        gate: threading.Event, caplog: pytest.LogCaptureFixture) -> None:
    # a background plan ready after its splice time was planned again for the same time: the notes then too close
    # to prepare (its first three) were left out
    kit = load_kit("default")
    physics = LivePhysicsCore(planner="thread", scene="drummer", kit=kit, grip="german", pose_rate_hz=0, mode="live")
    assert physics.score_player.wait_loaded(120.0)  # as the node before it listens (play: refused meanwhile)
    physics.score_player.library = [SCORE.parent]
    recorder = RecorderCore()
    runner = OfflineRunner([physics, InteractionCore(kit=kit), recorder])
    control: Any = runner.bus.endpoint("control")
    player = physics.score_player
    runner.run_until(1.0)
    control.send(ScoreLoad(path=SCORE.name), "physics")
    control.send(ScoreTransport(action="play", time=2.5, position=0.0), "physics")
    runner.run_until(2.3)  # its plan is held past its splice time: planned again, the first note is 0.2 s away
    with caplog.at_level("WARNING", logger="batteur.physics.score"):
        gate.set()
        while player.busy:
            assert player.wait(60.0)
            runner.run_until(runner.now + 0.002)
    assert player.mapping is not None
    start = player.mapping[0]
    runner.run_until(start + read_score(SCORE).duration + 0.5)
    physics.close()
    assert player.late_notes == 0 and physics.rejected == {}
    assert start > 2.5
    assert any("too close to prepare its first note" in r.getMessage() for r in caplog.records)
    assert first_note_missed(recorder, start) == []
