"""A pick-up is bar 0 only where the score has a bar after it: a one-bar score is bar 1, whatever its meter."""

from __future__ import annotations

from pathlib import Path

import pytest

from common.score.bars import counted_bars
from common.score.position import counted_bar_beat, pickup
from common.score.text import parse_text
from tests.cli.test_compare import START, report, write_take


@pytest.mark.parametrize("meter", ["1/16", "1/8", "3/8", "1/4", "4/4"])
def test_a_one_bar_score_is_bar_1(meter: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A bar of 1/16 ends before the beat the score's beats are padded to: the start after it, where the score
    ends, read as a second bar four times as long, the bar as its pick-up (bars 0-0, "bar 0, beat 3")."""
    text = f"tempo 120\nmeter {meter}\nSN |x|\n"
    score = parse_text(text)
    assert pickup(score) is None and counted_bars(score) == (1, 1)
    assert counted_bar_beat(score, 0.0)[:2] == (1, 1.0)
    exercise = tmp_path / "one.txt"
    exercise.write_text(text, encoding="utf-8")
    got = report([str(exercise), str(write_take(tmp_path / "take.mid", [(START, 38, 100)]))], capsys)
    assert got["pickup_beats"] is None and [b["bar"] for b in got["bars"]] == [1]


def test_a_pick_up_before_a_bar_is_still_bar_0() -> None:
    score = parse_text("tempo 120\nmeter 1/4\nSN |x|\nmeter 4/4\nSN |x.x.x.x.|\n")
    assert pickup(score) == (1.0, 4.0) and counted_bars(score) == (0, 1)
