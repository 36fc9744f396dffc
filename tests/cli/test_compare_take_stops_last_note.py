"""``batteur compare``: "the take stops" is measured against the exercise's last written note, not the end of its
last bar: a take missing only its last note, a quiet one just after the last strike, played to the end."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.cli.test_compare import report, run, write_take, written

START = 1.0

ENDS_EARLY = """\
tempo 120
meter 4/4
HH |x.x.x.x.x.x.x.x.|x.x.x.x.x.x.x.x.|x.x.x.x.x.x.x.x.|x.x.x...........|
SN |....x.......x...|....x.......x...|....x.......x...|....x...........|
BD |x.......x.x.....|x.......x.x.....|x.......x.x.....|x.......x.......|
"""
"""Three bars of rock and a last one stopping on beat 3's kick (7 s), the bar ending at 8 s."""


def test_a_last_note_missed_just_after_the_last_strike_is_no_early_stop(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    exercise = tmp_path / "exercise.txt"
    exercise.write_text(ENDS_EARLY, encoding="utf-8")
    notes = written(exercise)
    last = max(t for t, _, _ in notes)
    take = write_take(tmp_path / "take.mid", [(START + t, p, v) for t, p, v in notes if t < last])
    got = report([str(exercise), str(take)], capsys)
    assert got["missed"] == 1 and got["take_stops"] is None
    assert [m["after_take"] for m in got["misses"]] == [False]
    _, out, _ = run([str(exercise), str(take)], capsys)
    assert "the take stops" not in out and "bar 4, beat 3: kick missed" in out
    # stopping a bar before the last note still is an early stop
    take = write_take(tmp_path / "stops.mid", [(START + t, p, v) for t, p, v in notes if t < last - 2.0])
    got = report([str(exercise), str(take)], capsys)
    assert got["take_stops"] is not None and got["take_stops"]["bar"] == 3
