"""The live warnings of physics falling behind say where in the score it happened, in bars and beats.

Until 8 Dec they gave counts alone ("100 steps behind the rig clock, 50 skipped, 50 in all"; "the notes between are
skipped"), and a teacher on a loaded machine could not tell which bars the students heard late or not at all. The
skip's warning now says the bar the drummer plays (``while playing groove.txt bar 1 beat 2.6``), a jump's the
stretch it skips (``(groove.txt bar 1 beat 2.6 to bar 1 beat 4.5)``); with no score playing they read as before.

Deterministic: a live core (plans in the handler) stepped by a clock that stalls once for 1.2 s, as
tests/physics/test_live_skipped_notes.py.
"""

from __future__ import annotations

import logging
from pathlib import Path

import pytest

from common.kit import load_kit
from common.messages.score import ScoreLoad, ScoreLoop, ScoreTransport
from services.physics.core import PhysicsCore
from tests.physics.test_score_loop import BAR_S, FIVE_BARS

LOGGER = "batteur.physics"
# 100 bpm: a beat is 0.6 s; two 4/4 bars of hi-hat and kick
GROOVE = """tempo 100
meter 4/4
HH |X.x.X.x.X.x.X.x.|X.x.X.x.X.x.X.x.|
BD |x.......x.x.....|x.......x.x.....|
"""
PLAY_AT_S, STALL_AT_MS, STALL_MS = 1.0, 2000, 1200


@pytest.mark.slow  # 2 s of drummer simulation: 3-10 s
def test_the_behind_warnings_say_the_bars(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    (tmp_path / "groove.txt").write_text(GROOVE, encoding="utf-8")
    core = PhysicsCore(scene="drummer", kit=load_kit("default"), grip="german", pose_rate_hz=0, mode="live")
    try:
        for k in range(1, 201):
            core.step(k / 1000)
        player = core.score_player
        player.load(tmp_path / "groove.txt", trusted=True)
        player.play(PLAY_AT_S, 0.0, core.time)
        now_ms = round(core.time * 1000)
        with caplog.at_level(logging.WARNING, logger=LOGGER):
            while now_ms < STALL_AT_MS + STALL_MS + 100:
                now_ms += STALL_MS + 1 if now_ms == STALL_AT_MS else 1
                core.step(now_ms / 1000)
        said = [r.getMessage() for r in caplog.records if r.getMessage().startswith("physics is ")]
        # the stall: at rig 2.0 s the groove is 1.0 s in (bar 1, beat 1 + 1.0 / 0.6); the targets stay there
        # (trailing the rig clock by the 1.151 s skipped), then jump to where the rig clock is, 2.151 s in
        skip = next(s for s in said if "steps behind the rig clock" in s)
        assert skip.startswith("physics is 1201 ms behind real time while playing groove.txt bar 1 beat 2.6: notes "
                               "play late or are skipped; "), skip  # was "... real time: notes play late ..."
        jump = next(s for s in said if "the strokes between dropped" in s)
        assert ("the drummer's hands jump to catch up and the notes between are skipped (groove.txt bar 1 beat 2.6 "
                "to bar 1 beat 4.5); give physics") in jump, jump
        # the notes of that stretch: hi-hats at score 1.2, 1.5, 1.8, 2.1 s and kicks at 1.2, 1.5 s
        assert "0 live notes (each refused to its sender) and 6 score notes" in jump, jump
    finally:
        core.close()


def test_no_score_playing_no_bars(tmp_path: Path) -> None:
    """Live notes alone, or nothing: the warnings say no score position (there is none)."""
    core = PhysicsCore(scene="drummer", kit=load_kit("default"), grip="german", pose_rate_hz=0, mode="live")
    try:
        assert core.score_player.where(1.0) == "" and core._playing_words() == ""
        assert core._skipped_words(1.0, 2.0) == ""
    finally:
        core.close()


def test_a_looped_play_is_said_in_the_bars_looped(tmp_path: Path) -> None:
    """Bars 3-4 looped: the second pass is bar 3 again (as the stop and pause lines say it), not bar 5 of the passes
    laid end to end; a stretch past the play's end is said to its end. Planning only (no physics steps)."""
    (tmp_path / "five.txt").write_text(FIVE_BARS, encoding="utf-8")
    core = PhysicsCore(scene="drummer", kit=load_kit("default"), grip="german", pose_rate_hz=0)
    try:
        player = core.score_player
        player.library = [tmp_path]
        core.handle(ScoreLoad(path="five.txt"), 0.0, "127.0.0.1:9")
        core.handle(ScoreLoop(first=3, last=4), 0.0, "127.0.0.1:9")
        core.handle(ScoreTransport(action="play", time=1.0, position=0.0), 0.0, "127.0.0.1:9")
        assert core.rejected == {}
        start = 1.0 + 4 * BAR_S  # bar 3's first pass; its second pass 2 bars later
        assert player.where(start + 2 * BAR_S + 0.5) == "five.txt bar 3 beat 2.0"
        assert player.where(0.5) == "five.txt before bar 1 beat 1.0"  # before the play's first note
        assert player.where(start, start + 2 * BAR_S + 1.0) == "five.txt bar 3 beat 1.0 to bar 3 beat 3.0"
        assert player.where(player.end_time - 0.5, player.end_time + 5.0).endswith(" to its end")
    finally:
        core.close()
