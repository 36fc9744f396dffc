"""``batteur compare``: a lag growing in a bar's last beat alone is notes off, not a tempo. Four bars of 120 bpm
played exactly but two snare notes of a fill on bar 2's beat 4 and 4& 60 and 120 ms early read "running ahead in bar
2: played at about 127 bpm" (until 7 Dec); a bar slowing down then a pause read "falling behind in bar
3". A run is told only when its lag grows over a bar's worth of beats (the tempo change played slow of
test_compare_tempo_lag still is)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from common.score.text import read_score
from tests.cli.test_compare import PITCH, START, report, run, write_take

EXERCISE = """\
tempo 120
meter 4/4
HH |x.x.x.x.|x.x.x...|x.x.x.x.|x.x.x.x.|
SN |..x...x.|..x...xx|..x...x.|..x...x.|
BD |x...x...|x...x...|x...x...|x...x...|
"""
"""Four bars of rock at 120 bpm, bar 2 ending on a snare fill on beat 4 and 4& (3.5 and 3.75 s)."""


def _take(exercise: Path, path: Path, shift: Callable[[float, str], float]) -> Path:
    """The exercise played exactly but each note ``shift(written time s, event)`` s off (a 0.5 ms tick)."""
    return write_take(path, [(round((START + e.time + shift(e.time, e.event.value)) * 2000) / 2000,
                              PITCH[e.event.value], 100) for e in read_score(exercise).events])


@pytest.fixture
def exercise(tmp_path: Path) -> Path:
    path = tmp_path / "fill.txt"
    path.write_text(EXERCISE)
    return path


def test_a_fill_played_early_is_two_notes_early_not_a_tempo(exercise: Path, tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    early = {3.5: -0.06, 3.75: -0.12}
    take = _take(exercise, tmp_path / "fill.mid", lambda t, e: early.get(round(t, 3), 0.0) if e == "SNARE" else 0.0)
    got = report([str(exercise), str(take)], capsys)
    assert got["off_tempo"] == []
    assert (got["played"], got["off_tolerance"], got["missed"], got["extra"]) == (30, 2, 0, 0)
    _, out, _ = run([str(exercise), str(take)], capsys)
    assert "running ahead" not in out and "bpm where" not in out
    assert "bar 2, beat 4: snare played 60 ms early" in out
    assert "bar 2, beat 4&: snare played 120 ms early" in out


def test_a_bar_slowing_down_then_a_pause_is_no_tempo_run(exercise: Path, tmp_path: Path,
                                                         capsys: pytest.CaptureFixture[str]) -> None:
    """Bar 3 10 % slower as it goes (0 to 150 ms late by its beat 4), a 0.4 s pause, bar 4 on tempo 0.6 s late."""
    def rit(t: float, _: str) -> float:
        return 0.0 if t < 4.0 else (t - 4.0) * 0.1 if t < 6.0 else 0.6

    got = report([str(exercise), str(_take(exercise, tmp_path / "rit.mid", rit))], capsys)
    assert got["off_tempo"] == []
    _, out, _ = run([str(exercise), str(_take(exercise, tmp_path / "rit.mid", rit))], capsys)
    assert "falling behind" not in out
