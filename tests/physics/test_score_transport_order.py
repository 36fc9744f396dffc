"""Score transport messages in the orders a user sends them: a tempo change before the start, a stop or pause
scheduled ahead (the score plays, and its position is shown, until then).

The core is driven offline through its handler (rig times as sent; no wall clock).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from common.messages.score import ScoreLoad, ScoreTransport, TempoScale
from common.score.text import read_score
from services.physics.core import PhysicsCore

SCORES = Path(__file__).parents[1] / "render"
SCORE = SCORES / "short_groove.txt"
SOURCE = "127.0.0.1:9"


@pytest.fixture
def core() -> Iterator[PhysicsCore]:
    physics = PhysicsCore(scene="drummer", grip="german", pose_rate_hz=0)
    physics.score_player.library = [SCORES]
    physics.handle(ScoreLoad(path=SCORE.name), 0.0, SOURCE)
    yield physics
    physics.close()


def test_a_tempo_change_before_the_start_keeps_the_asked_start(core: PhysicsCore) -> None:
    """play TIME POSITION: POSITION sounds at TIME. A tempo change sent before TIME re-times the notes after it
    at the new tempo; it does not move the start (it moved it 0.7 s later: the score position was extrapolated
    back before POSITION)."""
    player = core.score_player
    written = sorted({e.time for e in read_score(SCORE).events if e.time >= 0.6 - 1e-6})
    core.handle(ScoreTransport(action="play", time=3.0, position=0.6), 0.0, SOURCE)
    core.handle(TempoScale(factor=0.5), 0.1, SOURCE)
    assert core.rejected_total == 0 and player.state == "playing"
    assert player.mapping == pytest.approx((3.0, 0.6, 0.5))
    strokes = sorted({round(e.time, 6) for e in player.events})
    assert strokes == pytest.approx([3.0 + (t - 0.6) / 0.5 for t in written])



@pytest.mark.parametrize("action", ["stop", "pause"])
def test_a_stop_or_pause_sent_ahead_leaves_the_position_shown_until_its_time(tmp_path: Path, action: str) -> None:
    """The score plays until the time a stop or pause was asked for, and the view's panel shows where it is until
    then (the positions stopped when the message arrived: 2 s early here); from then on it shows none."""
    from tests.physics.test_live_score_position import playing_with_view

    physics, graphics, runner, control = playing_with_view(tmp_path)
    try:
        runner.run_until(2.0)
        control.send(ScoreTransport(action=action, time=4.0, position=0.0), "physics")
        runner.run_until(3.5)  # score time 2 s: bar 0, beat 3.33 (a position older than 1 s is not shown)
        panel = graphics.status(runner.now)["score"]
        assert isinstance(panel, dict) and panel["bar"] == 0 and panel["beat"] == pytest.approx(3.33, abs=0.2)
        runner.run_until(5.2)
        assert graphics.status(runner.now)["score"] is None  # stopped (paused) at 4 s: nothing sent since
        assert physics.rejected_total == 0
    finally:
        physics.close()
