"""``batteur compare``: a student who comes in late or early after a written rest miscounted the rest: the entry is
said (``bar 5: came in 0.5 s late after the rest (bars 3-4)``) and the notes after it are told late or early, not
re-timed away as a restart (until 7 Dec a beat late after a 2-bar rest read as a restart and then a perfect take,
a beat early as 5 missed and 5 extra); a pause where nothing is written to rest is still a restart, and a pause
after the take's first notes or before its last ones counts them as played (they were missed, and the notes
played for them silently before or after the exercise)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.cli.test_compare import START, report, run, write_take, written

ROWS = {"HH": "X.x.X.x.X.x.X.x.", "SN": "....x.......x...", "BD": "x.......x.x....."}
"""The rock bar of tests/cli/test_compare.py: 13 notes, 2 s at 120 bpm (a beat 0.5 s)."""


def exercise(path: Path, bars: list[bool], rows: dict[str, str] | None = None) -> Path:
    """An exercise of ``bars``: the rock bar where True, a bar's rest where False."""
    rows = rows or ROWS
    path.write_text("tempo 120\nmeter 4/4\n" + "".join(
        f"{k} |{'|'.join(v if played else '.' * 16 for played in bars)}|\n" for k, v in rows.items()),
        encoding="utf-8")
    return path


def shifted(exercise_path: Path, path: Path, at: float, by: float) -> Path:
    """The exercise played as written from :data:`START`, its notes from written time ``at`` on ``by`` s later."""
    return write_take(path, [(START + t + (by if t >= at - 1e-9 else 0.0), p, v)
                             for t, p, v in written(exercise_path)])


@pytest.mark.parametrize("by", [0.5, 0.3, -0.5, -0.3, 0.2])
def test_an_entry_after_a_written_rest_is_said_and_its_notes_kept_late_or_early(
        by: float, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Two bars, two bars' rest, two bars; the last two come in ``by`` s late (- early): bars 1-2 played, bars 5-6
    each note ``by`` off, the entry said at bar 5 after the rest of bars 3-4, with or without ``--offset``. 0.2 s
    late: all 52 notes also match at 117 bpm (each within the tolerance), no tempo to say for a steady take."""
    path = exercise(tmp_path / "rest.txt", [True, True, False, False, True, True])
    take = shifted(path, tmp_path / "take.mid", 8.0, by)
    for forced in ([], ["--offset", str(START)]):
        got = report([str(path), str(take), *forced], capsys)
        assert got["restarts"] == []
        assert got["offset_s"] == pytest.approx(START, abs=1e-3)
        assert [(e["bar"], e["beat"], e["rest"]) for e in got["rest_entries"]] == [(5, 1.0, "bars 3-4")]
        assert got["rest_entries"][0]["late_s"] == pytest.approx(by, abs=1e-3)
        assert got["rest_entries"][0]["late_beats"] == pytest.approx(by / 0.5, abs=0.01)
        assert got["rest_entries"][0]["take_time_s"] == pytest.approx(START + 8.0 + by, abs=1e-3)
        assert (got["played"], got["off_tolerance"], got["missed"], got["extra"], got["outside"]) == (26, 26, 0, 0, 0)
        off = [m for m in got["misses"] if "played_off_by_ms" in m]
        assert {m["bar"] for m in off} == {5, 6} and len(off) == 26
        assert all(m["played_off_by_ms"] == pytest.approx(by * 1000, abs=0.6) for m in off)
        assert [b["mean_ms"] for b in got["bars"] if b["bar"] in (1, 2)] == [0, 0]
        _, out, _ = run([str(path), str(take), *forced], capsys)
        how = "late" if by > 0 else "early"
        beats = f"{abs(by) / 0.5:g} beat" + ("" if abs(by) == 0.5 else "s")
        assert f"bar 5: came in {abs(by):.1f} s {how} ({beats}) after the rest (bars 3-4)" in out
        assert "came back in" not in out


def test_a_pause_in_a_quarter_note_groove_is_still_a_restart(tmp_path: Path,
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    """Notes a beat apart rest nowhere (:data:`batteur.compare.REST_BEATS`): a 0.6 s pause before bar 3 is the
    student stopping and coming back in, timed from there (as 14ef6b2's groove pause, still a restart below)."""
    rows = {"HH": "x...x...x...x...", "BD": "x.......x......."}
    path = exercise(tmp_path / "quarters.txt", [True] * 4, rows)
    got = report([str(path), str(shifted(path, tmp_path / "take.mid", 4.0, 0.6))], capsys)
    assert got["rest_entries"] == []
    assert [(r["bar"], r["late_s"]) for r in got["restarts"]] == [(3, pytest.approx(0.6, abs=1e-3))]
    assert (got["played"], got["off_tolerance"], got["missed"], got["extra"]) == (24, 0, 0, 0)


@pytest.mark.parametrize(("pause_at", "bar"), [(2.0, 2), (10.0, 6)])
def test_a_pause_in_the_groove_is_a_restart_beside_an_entry_after_the_rest(
        pause_at: float, bar: int, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The groove paused 0.6 s before bar 2 or bar 6 (nothing written to rest there: a restart, timed from it),
    bar 5 entered a beat late after the rest of bars 3-4 (its notes late; the take lined up as one matches bars
    5-7 there, bars 1-2 a beat off)."""
    path = exercise(tmp_path / "rest.txt", [True, True, False, False, True, True, True])
    notes = [(START + t + (0.6 if t >= pause_at else 0.0) + (0.5 if t >= 8.0 else 0.0), p, v)
             for t, p, v in written(path)]
    got = report([str(path), str(write_take(tmp_path / "take.mid", notes))], capsys)
    assert got["offset_s"] == pytest.approx(START, abs=1e-3)
    assert [(r["bar"], r["beat"], r["late_s"]) for r in got["restarts"]] == [(bar, 1.0, pytest.approx(0.6))]
    assert [(e["bar"], e["late_s"], e["rest"]) for e in got["rest_entries"]] == [
        (5, pytest.approx(0.5, abs=1e-3), "bars 3-4")]
    assert (got["played"], got["off_tolerance"], got["missed"], got["extra"]) == (26, 39, 0, 0)


@pytest.mark.parametrize("back", [0.3, 0.5])
def test_a_second_entry_is_told_against_the_start(back: float, tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """Bar 5 a beat late after bars 3-4's rest, bar 7 ``back`` s earlier than that after bar 6's: 0.2 s late, as
    its notes are told; or back on time, nothing said and its notes played."""
    path = exercise(tmp_path / "rest.txt", [True, True, False, False, True, False, True])
    notes = [(START + t + (0.5 if t >= 8.0 else 0.0) - (back if t >= 12.0 else 0.0), p, v)
             for t, p, v in written(path)]
    got = report([str(path), str(write_take(tmp_path / "take.mid", notes))], capsys)
    late = 0.5 - back
    entries = [(5, pytest.approx(0.5, abs=1e-3), "bars 3-4")] + ([(7, pytest.approx(late, abs=1e-3), "bar 6")]
                                                                if late else [])
    assert [(e["bar"], e["late_s"], e["rest"]) for e in got["rest_entries"]] == entries
    off = {m["bar"]: m["played_off_by_ms"] for m in got["misses"]}
    assert off == {5: pytest.approx(500, abs=1), **({7: pytest.approx(late * 1000, abs=1)} if late else {})}
    assert (got["played"], got["off_tolerance"], got["missed"], got["extra"]) == (
        (26, 26, 0, 0) if late else (39, 13, 0, 0))


@pytest.mark.parametrize(("at", "bar", "beat"), [(0.5, 1, 2.0), (7.5, 4, 4.0)])
def test_a_pause_after_the_first_beat_or_before_the_last_counts_its_notes(
        at: float, bar: int, beat: float, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A 1 s pause after the first beat's 3 notes, or before the last beat's 3: fewer than
    :data:`batteur.compare.RESTART_NOTES` on that side, they were missed and the notes played for them silently
    before or after the exercise (0 extra, until 7 Dec); now a restart with every note played."""
    path = exercise(tmp_path / "groove.txt", [True] * 4)
    got = report([str(path), str(shifted(path, tmp_path / "take.mid", at, 1.0))], capsys)
    assert [(r["bar"], r["beat"], r["late_s"]) for r in got["restarts"]] == [(bar, beat, pytest.approx(1.0))]
    assert (got["played"], got["off_tolerance"], got["missed"], got["extra"]) == (52, 0, 0, 0)
