"""Each score loaded plays at its own tempo and dynamics: a tempo or dynamics factor set before the load (for the
score playing then, or for none) is reset to as written for the new score's play, and the node says so.

Until 8 Dec they carried over: a groove slowed to x0.5 and made louder for practice had the next piece loaded play
at half its tempo and louder, and nothing said why. The score still playing at the load keeps its factors (its
re-plans, a style change or a loop's more passes, stayed at them); a factor sent after the load is the new score's
too. The player runs on a bare PhysicsCore (no physics steps: planning only), as
tests/physics/test_score_load_while_playing.py.
"""

from __future__ import annotations

import logging
from pathlib import Path

import pytest

from common.kit import EventType, load_kit
from common.messages.physics import PhysicsReset
from common.messages.score import GestureStyle, ScoreDynamics, ScoreLoad, ScoreTransport, TempoScale
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
# another score: snares at 60 bpm, one a second, accents on the first of each bar
SNARES = """tempo 60
meter 4/4
SN |X...x...x...x...|X...x...x...x...|
"""


def _core(tmp_path: Path) -> tuple[PhysicsCore, ScorePlayer]:
    (tmp_path / "groove.txt").write_text(GROOVE, encoding="utf-8")
    (tmp_path / "snares.txt").write_text(SNARES, encoding="utf-8")
    core = PhysicsCore(scene="drummer", kit=load_kit("default"), grip="german", pose_rate_hz=0)
    core.score_player.library = [tmp_path]
    return core, core.score_player


def _said(caplog: pytest.LogCaptureFixture, part: str) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name == LOGGER and part in r.getMessage()]


def _snares(player: ScorePlayer) -> list[tuple[float, float]]:
    """(time s, velocity) of the snare notes planned."""
    return [(e.time, e.velocity) for e in player.events if e.event == EventType.SNARE]


def test_a_score_loaded_plays_at_its_own_tempo_and_dynamics(tmp_path: Path,
                                                            caplog: pytest.LogCaptureFixture) -> None:
    core, player = _core(tmp_path)
    try:
        with caplog.at_level(logging.INFO, logger=LOGGER):
            core.handle(ScoreLoad(path="groove.txt"), 0.0, SENDER)
            core.handle(TempoScale(factor=0.5), 0.0, SENDER)
            core.handle(ScoreDynamics(factor=2.0), 0.0, SENDER)
            core.handle(ScoreTransport(action="play", time=1.0, position=0.0), 0.0, SENDER)
            assert player.mapping == (1.0, 0.0, 0.5)
            core.handle(ScoreLoad(path="snares.txt"), 2.0, SENDER)  # while the groove plays
            assert (player.tempo, player.dynamics) == (1.0, 1.0)
            # the groove plays on at its factors: a style change re-plans it at x0.5 (was x1 once the load reset
            # the next play's factors, had the re-plan read them)
            core.handle(GestureStyle(grip="german", nuance="tenuto", algorithm="simple", sticking="none"), 2.1,
                        SENDER)
            assert player.mapping is not None and player.mapping[2] == 0.5
            core.handle(ScoreTransport(action="play", time=8.0, position=0.0), 7.0, SENDER)
        assert core.rejected == {}
        assert player.mapping == (8.0, 0.0, 1.0)  # was (8.0, 0.0, 0.5): the groove's tempo
        written = [(e.time + 8.0, e.velocity) for e in player.score.events]  # type: ignore[union-attr]
        played = _snares(player)
        assert len(played) == len(written)  # one a second, velocities as written (were doubled)
        assert [x for pair in played for x in pair] == pytest.approx([x for pair in written for x in pair])
        assert _said(caplog, "plays at its own tempo") == [
            "snares.txt plays at its own tempo and dynamics: tempo x0.5 and dynamics x2 reset to x1 (as written) for "
            "its play; groove.txt plays on with them; send /batteur/score/tempo or /batteur/score/dynamics after the "
            "load to change them"]
        assert _said(caplog, "re-planned from")[0].endswith(": tempo x0.5, dynamics x2, german grip, tenuto")
    finally:
        core.close()


def test_a_factor_sent_after_the_load_is_the_new_scores(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    """Load, then tempo, then play (a performer preparing the next piece): the tempo holds; loading the same score
    again starts it as written, and nothing is said when there was nothing to reset."""
    core, player = _core(tmp_path)
    try:
        with caplog.at_level(logging.INFO, logger=LOGGER):
            core.handle(ScoreLoad(path="snares.txt"), 0.0, SENDER)
            core.handle(TempoScale(factor=2.0), 0.0, SENDER)
            core.handle(ScoreTransport(action="play", time=1.0, position=0.0), 0.0, SENDER)
            assert player.mapping == (1.0, 0.0, 2.0)
            assert [t for t, _ in _snares(player)][:3] == pytest.approx([1.0, 1.5, 2.0])
            core.handle(PhysicsReset(time=0.0), 1.2, SENDER)  # nothing plays on (a bare core is not stepped)
            core.handle(ScoreLoad(path="snares.txt"), 3.0, SENDER)
            core.handle(ScoreTransport(action="play", time=5.0, position=0.0), 3.0, SENDER)
        assert core.rejected == {}
        assert player.mapping == (5.0, 0.0, 1.0)
        said = _said(caplog, "plays at its own tempo")
        assert said == ["snares.txt plays at its own tempo and dynamics: tempo x2 reset to x1 (as written) for its "
                        "play; send /batteur/score/tempo or /batteur/score/dynamics after the load to change them"]
    finally:
        core.close()
