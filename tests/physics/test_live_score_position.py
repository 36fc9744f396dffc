"""The live node tells the view where the score it plays is (bar, beat, tempo for the status panel)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from common.bus import OfflineRunner
from common.kit import load_kit
from common.messages.score import ScoreLoad, ScoreTransport, TempoScale
from services.graphics.core import GraphicsCore, GraphicsSettings
from services.physics.node import LivePhysicsCore

SCORE = "tempo 100\nmeter 4/4\nHH |x.x.x.x.|x.x.x.x.|x.x.x.x.|x.x.x.x.|\nBD |x...x...|x...x...|x...x...|x...x...|\n"
"""Four bars at 100 bpm: a beat every 0.6 s."""


def _panel(graphics: GraphicsCore, now: float) -> dict[str, float] | None:
    score = graphics.status(now)["score"]
    assert score is None or isinstance(score, dict)
    return score


def playing_with_view(library: Path) -> tuple[LivePhysicsCore, GraphicsCore, OfflineRunner, Any]:
    """The live core (plans in a thread) and the view's core on the in-memory bus, :data:`SCORE` (written to
    ``library`` as four_bars.txt) asked to play from rig time 1.5 s, its plan spliced: (physics, graphics,
    runner, control endpoint). Close ``physics`` after."""
    (library / "four_bars.txt").write_text(SCORE)
    kit = load_kit("default")
    physics = LivePhysicsCore(planner="thread", scene="drummer", kit=kit, grip="german", pose_rate_hz=0,
                              mode="live")
    assert physics.score_player.wait_loaded(120.0)  # as the node before it listens (play: refused meanwhile)
    physics.score_player.library = [library]
    graphics = GraphicsCore(GraphicsSettings(clock="rig"), kit=kit)
    runner = OfflineRunner([physics, graphics])
    control = runner.bus.endpoint("control")
    control.send(ScoreLoad(path="four_bars.txt"), "physics")
    control.send(ScoreTransport(action="play", time=1.5, position=0.0), "physics")
    assert physics.score_player.wait(60.0)
    return physics, graphics, runner, control


def test_the_view_shows_bar_beat_and_tempo_while_the_score_plays_and_nothing_after(tmp_path: Path) -> None:
    physics, graphics, runner, control = playing_with_view(tmp_path)
    player = physics.score_player
    try:
        runner.run_until(1.2)
        assert _panel(graphics, runner.now) is None  # nothing before the score's first beat
        runner.run_until(1.5 + 3.3 * 0.6)  # score time 1.98 s: beat 3.3, bar 0
        panel = _panel(graphics, runner.now)
        assert panel is not None
        assert panel["bar"] == 0 and panel["beat"] == pytest.approx(3.3, abs=0.11)  # sent every 0.1 s
        assert panel["tempo_bpm"] == pytest.approx(100.0)
        control.send(TempoScale(factor=2.0), "physics")  # the tempo shown is the one played
        assert player.wait(60.0)
        runner.run_until(runner.now + 0.5)
        panel = _panel(graphics, runner.now)
        assert panel is not None and panel["bar"] == 1 and panel["tempo_bpm"] == pytest.approx(200.0)
        runner.run_until(player.end_time + 1.2)
        assert _panel(graphics, runner.now) is None  # the score ended: the panel empties
    finally:
        physics.close()


def test_a_score_loaded_while_one_plays_leaves_the_view_in_the_playing_scores_bars(tmp_path: Path) -> None:
    # the load is for the next play (the playing score plays on): its bars must not be read on the playing clock
    (tmp_path / "waltz.txt").write_text("tempo 60\nmeter 3/4\nSN |x.x.x.|x.x.x.|x.x.x.|\n")
    physics, graphics, runner, control = playing_with_view(tmp_path)
    try:
        runner.run_until(2.0)
        control.send(ScoreLoad(path="waltz.txt"), "physics")
        runner.run_until(1.5 + 3.0)  # four_bars' score time 3.0 s: bar 1 beat 1.0 (the waltz's: bar 1 beat 0.0)
        panel = _panel(graphics, runner.now)
        assert panel is not None
        assert panel["bar"] == 1 and panel["beat"] == pytest.approx(1.0, abs=0.2)
        assert panel["tempo_bpm"] == pytest.approx(100.0)
    finally:
        physics.close()
