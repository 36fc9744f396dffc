"""``batteur compare``: a pause with fewer than :data:`batteur.compare.RESTART_NOTES` written notes on one side is
a restart only when the student really stopped (:data:`batteur.compare.STOP_BEATS` beyond the written gap): a
groove's last crash and kick held 0.35 or 0.6 s on, or its first downbeat 0.4 s early, are those notes played late
or early, told with their error (until 7 Dec "came back in 0.4 s late at bar 9 ... after a pause" and a perfect
take); a 1 s pause there is still a restart (tests/cli/test_compare_rest_entry.py)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

import tests.cli.test_compare as tc
from tests.cli.test_compare import START, report, run, write_take, written

ROWS = {"HH": "X.x.X.x.X.x.X.x.", "SN": "....x.......x...", "BD": "x.......x.x.....", "CR": "." * 16}
"""The rock bar of tests/cli/test_compare.py (2 s at 120 bpm, a beat 0.5 s), and a crash row."""


def groove(path: Path, bars: int, final_crash: bool) -> Path:
    """``bars`` rock bars, then (``final_crash``) a bar of one crash and kick on its downbeat."""
    last = {"CR": "x" + "." * 15, "BD": "x" + "." * 15}
    path.write_text("tempo 120\nmeter 4/4\n" + "".join(
        f"{k} |{'|'.join([v] * bars + ([last.get(k, '.' * 16)] if final_crash else []))}|\n"
        for k, v in ROWS.items()), encoding="utf-8")
    return path


def take(exercise: Path, path: Path, move: Callable[[float], float]) -> Path:
    """The exercise played from :data:`START`, each written time t at ``move(t)``."""
    return write_take(path, [(START + move(t), p, v) for t, p, v in written(exercise)])


@pytest.mark.parametrize("late", [0.35, 0.6])
def test_a_last_crash_held_late_is_played_late_not_a_restart(
        late: float, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    """8 bars, then bar 9's crash and kick ``late`` s late (a fermata): 104 played, those 2 late by it."""
    monkeypatch.setitem(tc.PITCH, "CRASH", 49)
    path = groove(tmp_path / "groove.txt", 8, True)
    played = take(path, tmp_path / "take.mid", lambda t: t + late if t >= 16.0 else t)
    got = report([str(path), str(played)], capsys)
    assert got["restarts"] == []
    assert got["offset_s"] == pytest.approx(START, abs=1e-3)
    assert (got["played"], got["off_tolerance"], got["missed"], got["extra"]) == (104, 2, 0, 0)
    off = sorted((m["drum"], m["bar"], m["played_off_by_ms"]) for m in got["misses"])
    assert off == [("crash", 9, pytest.approx(late * 1000, abs=0.6)), ("kick", 9, pytest.approx(late * 1000, abs=0.6))]
    _, out, _ = run([str(path), str(played)], capsys)
    assert "came back in" not in out
    assert f"bar 9, beat 1: crash played {late * 1000:.0f} ms late (beyond the tolerance)" in out


def test_a_first_downbeat_early_is_played_early_not_a_restart(tmp_path: Path,
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    """8 bars, the first downbeat (hi-hat and kick) 0.4 s early, the rest on time: 102 played, 2 early by it."""
    path = groove(tmp_path / "groove.txt", 8, False)
    played = take(path, tmp_path / "take.mid", lambda t: t - 0.4 if t < 1e-9 else t)
    got = report([str(path), str(played)], capsys)
    assert got["restarts"] == []
    assert got["offset_s"] == pytest.approx(START, abs=1e-3)
    assert (got["played"], got["off_tolerance"], got["missed"], got["extra"], got["outside"]) == (102, 2, 0, 0, 0)
    off = sorted((m["drum"], m["bar"], m["played_off_by_ms"]) for m in got["misses"])
    assert off == [("hihat", 1, pytest.approx(-400, abs=0.6)), ("kick", 1, pytest.approx(-400, abs=0.6))]
    _, out, _ = run([str(path), str(played)], capsys)
    assert "came back in" not in out
    assert "bar 1, beat 1: kick played 400 ms early (beyond the tolerance)" in out


@pytest.mark.parametrize(("at", "bar", "beat"), [(16.0, 9, 1.0), (0.5, 1, 2.0)])
def test_a_real_stop_there_is_still_a_restart(at: float, bar: int, beat: float, tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str],
                                              monkeypatch: pytest.MonkeyPatch) -> None:
    """A 1 s pause before the last crash, or after the first beat: the student stopped, a restart there."""
    monkeypatch.setitem(tc.PITCH, "CRASH", 49)
    path = groove(tmp_path / "groove.txt", 8, True)
    played = take(path, tmp_path / "take.mid", lambda t: t + 1.0 if t >= at - 1e-9 else t)
    got = report([str(path), str(played)], capsys)
    assert [(r["bar"], r["beat"], r["late_s"]) for r in got["restarts"]] == [(bar, beat, pytest.approx(1.0))]
    assert (got["played"], got["off_tolerance"], got["missed"], got["extra"]) == (106, 0, 0, 0)
