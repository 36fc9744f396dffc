"""``batteur compare``: a count-in on the hi-hat is not lined up with the exercise's first bar of quarter hi-hats
(the whole comparison one bar early, its first bar "missed", until 7 Dec)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.cli.test_compare import groove, report, run, write_take, written

START = 2.0
"""The exercise's first beat in the take: four hi-hats a beat (0.5 s) apart before it."""


@pytest.mark.parametrize("played_bars", [7, 6])
def test_a_hi_hat_count_in_does_not_shift_the_take_a_bar(played_bars: int, tmp_path: Path,
                                                         capsys: pytest.CaptureFixture[str]) -> None:
    """An 8-bar groove (hi-hats on the eighths, the beats accented) counted in on four closed hi-hats, the take
    stopping after ``played_bars`` bars: lined up a bar early the count-in matched bar 1's four beats and every
    bar played matched the next written one, 4 more than the truth."""
    exercise = tmp_path / "exercise.txt"
    exercise.write_text(groove(8), encoding="utf-8")
    count_in = [(START - 0.5 * k, 42, 100) for k in range(4, 0, -1)]
    notes = [(START + t, p, v) for t, p, v in written(exercise) if t < 2.0 * played_bars - 1e-9]
    path = write_take(tmp_path / "take.mid", count_in + notes)
    got = report([str(exercise), str(path)], capsys)
    assert got["offset_s"] == pytest.approx(START, abs=1e-3)
    assert (got["played"], got["missed"], got["extra"], got["outside"]) == (13 * played_bars,
                                                                            13 * (8 - played_bars), 0, 4)
    assert got["entry"] is not None and got["entry"]["on_time"]
    assert all(b["missed"] == 0 for b in got["bars"] if b["bar"] <= played_bars)
    _, out, _ = run([str(exercise), str(path)], capsys)
    assert "entered on the beat after the count-in" in out
    assert f"the take stops at bar {played_bars}" in out


def test_an_exercise_starting_on_quarter_hi_hats_is_not_taken_for_a_count_in(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The exercise's own first bar of quarter hi-hats, played with no count-in: those notes are the exercise's."""
    exercise = tmp_path / "exercise.txt"
    exercise.write_text("tempo 120\nmeter 4/4\nHH |x...x...x...x...|X.x.X.x.X.x.X.x.|X.x.X.x.X.x.X.x.|\n"
                        "SN |................|....x.......x...|....x.......x...|\n"
                        "BD |................|x.......x.x.....|x.......x.x.....|\n", encoding="utf-8")
    path = write_take(tmp_path / "take.mid", [(START + t, p, v) for t, p, v in written(exercise)])
    got = report([str(exercise), str(path)], capsys)
    assert got["offset_s"] == pytest.approx(START, abs=1e-3)
    assert (got["played"], got["missed"], got["extra"], got["outside"]) == (30, 0, 0, 0)
    assert got["entry"] is None


def test_a_counted_in_take_running_ahead_is_lined_up_on_its_start(tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """The walkthrough's b_ahead3: counted in, 3 % faster from bar 5 on, to the end; its last bars lost to the
    drift, a start a bar early (the count-in on bar 1's beats) matched one note more (until 7 Dec: "the exercise
    starts -0.001 s", bar 1 missed, the last bar "before or after the exercise")."""
    exercise = tmp_path / "exercise.txt"
    exercise.write_text(groove(8), encoding="utf-8")
    count_in = [(START - 0.5 * k, 42, 100) for k in range(4, 0, -1)]
    notes = [(START + (t if t < 8.0 else 8.0 + (t - 8.0) / 1.03), p, v) for t, p, v in written(exercise)]
    path = write_take(tmp_path / "take.mid", count_in + [(round(t * 2000) / 2000, p, v) for t, p, v in notes])
    got = report([str(exercise), str(path)], capsys)
    assert got["offset_s"] == pytest.approx(START, abs=2e-3) and got["outside"] == 4
    assert (got["missed"], got["extra"]) == (0, 0) and got["played"] + got["off_tolerance"] == 13 * 8
    assert got["entry"] is not None and got["entry"]["on_time"]
    [run_] = got["off_tempo"]
    assert (run_["direction"], run_["from_bar"], run_["to_bar"]) == ("ahead", 5, 8)
