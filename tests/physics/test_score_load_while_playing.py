"""A score loaded while another plays is for the next ``play``: the playing score plays on, and a tempo, style,
dynamics or loop change meanwhile re-plans the playing score, not the new one.

Until 7 Dec a tempo change after such a load re-planned the new score's notes on the old score's clock (the rest of
the groove became the new score's snares from the groove's position, said in the new score's bars). The player runs
on a bare PhysicsCore (no physics steps: planning only)."""

from __future__ import annotations

import logging
from pathlib import Path

import pytest

from common.kit import EventType, load_kit
from common.messages.score import ScoreLoad, ScoreLoop, ScoreTransport, TempoScale
from services.physics.core import PhysicsCore
from services.physics.score_player import ScorePlayer

SENDER = "127.0.0.1:9"
LOGGER = "batteur.physics.score"
# 100 bpm: a beat is 0.6 s; two 4/4 bars of hi-hat and kick, the last note at 4.5 s
GROOVE = """tempo 100
meter 4/4
HH |X.x.X.x.X.x.X.x.|X.x.X.x.X.x.X.x.|
BD |x.......x.x.....|x.......x.x.....|
"""
# another score: snares only, at 60 bpm in three bars
SNARES = """tempo 60
meter 4/4
SN |x...x...x...x...|x...x...x...x...|x...x...x...x...|
"""


def _player(tmp_path: Path) -> tuple[PhysicsCore, ScorePlayer]:
    (tmp_path / "groove.txt").write_text(GROOVE, encoding="utf-8")
    (tmp_path / "snares.txt").write_text(SNARES, encoding="utf-8")
    core = PhysicsCore(scene="drummer", kit=load_kit("default"), grip="german", pose_rate_hz=0)
    player = core.score_player
    player.library = [tmp_path]
    core.handle(ScoreLoad(path="groove.txt"), 0.0, SENDER)
    core.handle(ScoreTransport(action="play", time=1.0, position=0.0), 0.0, SENDER)
    return core, player


def _said(caplog: pytest.LogCaptureFixture, start: str) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name == LOGGER and r.getMessage().startswith(start)]


def test_a_tempo_change_after_a_load_re_plans_the_playing_score(tmp_path: Path,
                                                                caplog: pytest.LogCaptureFixture) -> None:
    core, player = _player(tmp_path)
    written = [(e.time, e.event) for e in player.events]
    with caplog.at_level(logging.INFO, logger=LOGGER):
        core.handle(ScoreLoad(path="snares.txt"), 2.0, SENDER)
        assert [(e.time, e.event) for e in player.events] == written  # the load alone changes nothing
        core.handle(TempoScale(factor=0.5), 2.1, SENDER)
    assert player.mapping is not None
    t_a, p_a, tempo = player.mapping
    core.close()
    assert tempo == 0.5 and core.rejected == {}
    # the groove's notes from the anchor on, at half speed; no snare of the score loaded since
    groove = [t for t, _ in written]
    after = [e for e in player.events if e.time >= t_a]
    assert {e.event for e in after} <= {EventType.HIHATCLOSED, EventType.HIHATOPEN, EventType.BASS}
    expected = sorted(t_a + (t - 1.0 - p_a) / 0.5 for t in groove if t - 1.0 >= p_a)
    assert sorted(e.time for e in after) == pytest.approx(expected, abs=1e-6)
    assert _said(caplog, "score snares.txt loaded") == [
        "score snares.txt loaded: 12 notes, 11.00 s; groove.txt plays on, snares.txt plays from the next play"]
    # said in the groove's bars (100 bpm), not the snares' (60 bpm)
    beat = 1 + p_a / 0.6
    assert _said(caplog, "re-planned from")[0].startswith(
        f"re-planned from rig {t_a:.3f} s (score {p_a:.3f} s, bar 1 beat {int(beat * 10) / 10:.1f})")


def test_a_loop_asked_after_a_load_is_the_new_scores_for_its_play(tmp_path: Path,
                                                                  caplog: pytest.LogCaptureFixture) -> None:
    core, player = _player(tmp_path)
    written = [(e.time, e.event) for e in player.events]
    plans = player.plans
    with caplog.at_level(logging.INFO, logger=LOGGER):
        core.handle(ScoreLoad(path="snares.txt"), 2.0, SENDER)
        core.handle(ScoreLoop(first=2, last=3), 2.1, SENDER)  # bars the groove does not have: the snares'
        assert player.plans == plans and [(e.time, e.event) for e in player.events] == written
        player.pump(player.end_time - 1.0)  # no more passes asked for the groove either
        assert player.plans == plans
        core.handle(ScoreTransport(action="play", time=8.0, position=0.0), 7.0, SENDER)
    core.close()
    assert core.rejected == {}
    assert _said(caplog, "loop bars 2-3 of snares.txt asked") == [
        "loop bars 2-3 of snares.txt asked: it starts with the next play"]
    snares = [e.time for e in player.events if e.event == EventType.SNARE]
    # bars 1-3 (4 s each), then bars 2-3 again from rig 20 s
    assert snares[:16] == pytest.approx([8.0 + k for k in range(12)] + [20.0 + k for k in range(4)], abs=1e-3)


def test_a_load_before_a_stop_sent_ahead_keeps_the_playing_scores_clock_until_the_stop(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    # the groove plays on until its stop: its position (the view's, a pause's words) stays until then; the load
    # dropped it (the clock once read in the loaded score's bars) and did not say the groove plays on
    core, player = _player(tmp_path)
    core.handle(ScoreTransport(action="stop", time=3.0, position=0.0), 2.0, SENDER)
    assert player.clock(2.5) == pytest.approx((1.0, 0.0, 1.0))
    with caplog.at_level(logging.INFO, logger=LOGGER):
        core.handle(ScoreLoad(path="snares.txt"), 2.1, SENDER)
        core.handle(ScoreTransport(action="pause", time=2.6, position=0.0), 2.2, SENDER)
    core.close()
    assert core.rejected == {}
    assert player.clock(2.5) == pytest.approx((1.0, 0.0, 1.0)) and player.clock(3.1) is None
    assert _said(caplog, "score snares.txt loaded") == [
        "score snares.txt loaded: 12 notes, 11.00 s; groove.txt plays on, snares.txt plays from the next play"]
    # 1.6 s into the groove at 100 bpm (a beat 0.6 s): bar 1 beat 3.6
    assert _said(caplog, "pause at") == ["pause at rig 2.600 s: score 1.600 s, bar 1 beat 3.6"]
