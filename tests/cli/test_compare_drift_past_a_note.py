"""``batteur compare``: a take that speeds up (slows down) in the middle and keeps that tempo is followed along its
lag past a note's spacing: once more than a sixteenth or an eighth ahead, its notes lie within the tolerance of
the neighbouring written ones, and were paired with them ("dragging, +32 ms" in a take 5 % fast, "the take
stops" with its last written notes missed, until 7 Dec)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.cli.test_compare import report, run, write_take, written

START = 1.0
"""The exercise's start in the take, s."""
CHANGE_S = 8.0
"""Written time (s, bar 5's downbeat at 120 bpm) from which the take plays faster (slower)."""

EIGHTHS = {"HH": "X.x.X.x.X.x.X.x.", "SN": "....x.......x...", "BD": "x.......x.x....."}
SIXTEENTHS = {"HH": "xxxxxxxxxxxxxxxx", "SN": "....x.......x...", "BD": "x.......x.x....."}


def exercise(tmp_path: Path, rows: dict[str, str], bars: int) -> Path:
    path = tmp_path / "exercise.txt"
    path.write_text("tempo 120\nmeter 4/4\n" + "".join(f"{k} |{'|'.join([v] * bars)}|\n" for k, v in rows.items()),
                    encoding="utf-8")
    return path


@pytest.mark.parametrize(("rows", "bars", "factor", "direction"), [
    (EIGHTHS, 8, 1.05, "ahead"),  # 381 ms ahead by the end: past an eighth (250 ms)
    (SIXTEENTHS, 8, 1.05, "ahead"),  # past three sixteenths (125 ms each)
    (SIXTEENTHS, 8, 0.95, "behind"),
])
def test_a_steady_drift_is_followed_past_a_note_s_spacing(rows: dict[str, str], bars: int, factor: float,
                                                          direction: str, tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    path = exercise(tmp_path, rows, bars)
    notes = [(START + (t if t < CHANGE_S else CHANGE_S + (t - CHANGE_S) / factor), p, v) for t, p, v in written(path)]
    take = write_take(tmp_path / "take.mid", [(round(t * 2000) / 2000, p, v) for t, p, v in notes])
    got = report([str(path), str(take)], capsys)
    assert got["offset_s"] == pytest.approx(START, abs=2e-3) and got["tempo"] is None
    assert (got["missed"], got["extra"], got["wrong_drum"], got["take_stops"]) == (0, 0, 0, None)
    assert got["played"] + got["off_tolerance"] == got["written"]
    bars_ = {b["bar"]: b for b in got["bars"]}
    feel = "rushed" if factor > 1 else "dragging"
    assert all(bars_[b]["feel"] == feel for b in range(6, bars + 1))  # none the other way
    for b in range(6, bars + 1):  # every note played for its own written note: the bar's tempo is the take's
        assert bars_[b]["bpm"] == pytest.approx(120 * factor, abs=0.5)
    [run_] = got["off_tempo"]
    assert (run_["direction"], run_["from_bar"], run_["to_bar"]) == (direction, 5, bars)
    assert run_["bpm"] == pytest.approx(120 * factor, abs=0.5)
    _, out, _ = run([str(path), str(take)], capsys)
    said = "running ahead" if factor > 1 else "falling behind"
    assert f"{said} in bars 5-{bars}: played at about {120 * factor:g} bpm" in out
    assert "the take stops" not in out
