"""``batteur compare``: a take that stops and comes back in is timed from the restart, not read as dragging; the
tables' columns line up whatever the means; a count-in is said only where the take has one."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from batteur.compare import main, summary_lines
from tests.cli.test_compare import EXERCISE, START, groove, report, run, write_take, written


def paused(exercise: Path, path: Path, pauses: list[tuple[float, float]]) -> Path:
    """The exercise played as written from :data:`START`, stopping ``pauses`` (written time s, pause s) before
    the notes from those times on."""
    return write_take(path, [(START + t + sum(pause for at, pause in pauses if t >= at - 1e-9), p, v)
                             for t, p, v in written(exercise)])


@pytest.mark.parametrize(("bars", "pauses", "said"), [
    # 0.6 s is a beat and 100 ms at 120 bpm: bars 3-4 read "dragging, +100 ms", paired with the next beat's notes
    (4, [(4.0, 0.6)], ["came back in 0.6 s late at bar 3, beat 1"]),
    # bars 3-8 after the pause are the longer part: lined up as bars 1-6, bars 1-2 were before the start
    (8, [(4.0, 0.6)], ["came back in 0.6 s late at bar 3, beat 1"]),
    (8, [(3.0, 0.7), (10.0, 1.1)], ["came back in 0.7 s late at bar 2, beat 3",
                                    "came back in 1.1 s late at bar 6, beat 1"]),
])
def test_a_pause_is_a_restart_not_a_drag(bars: int, pauses: list[tuple[float, float]], said: list[str],
                                         tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    exercise = tmp_path / "exercise.txt"
    exercise.write_text(EXERCISE if bars == 4 else groove(bars), encoding="utf-8")
    path = paused(exercise, tmp_path / "take.mid", pauses)
    for forced in ([], ["--offset", str(START)]):
        got = report([str(exercise), str(path), *forced], capsys)
        assert (got["played"], got["missed"], got["off_tolerance"], got["extra"]) == (13 * bars, 0, 0, 0)
        assert got["offset_s"] == pytest.approx(START, abs=1e-3) and got["tempo"] is None
        assert [r["late_s"] for r in got["restarts"]] == pytest.approx([pause for _, pause in pauses], abs=1e-3)
        assert [r["take_time_s"] for r in got["restarts"]] == pytest.approx(
            [START + at + sum(p for a, p in pauses if a <= at) for at, _ in pauses], abs=1e-3)
        assert all(b["mean_ms"] == 0 and b["feel"] is None for b in got["bars"])
        assert got["beats_rushed_dragging"] == []
        _, out, _ = run([str(exercise), str(path), *forced], capsys)
        assert [line.split(" after")[0] for line in out.splitlines() if line.startswith("came back")] == said
        assert "dragging" not in out


def test_a_jump_under_half_a_beat_is_no_restart(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A bar 200 ms late as a whole at 120 bpm (0.4 beat): its notes missed and extra, as before."""
    exercise = tmp_path / "exercise.txt"
    exercise.write_text(EXERCISE, encoding="utf-8")
    got = report([str(exercise), str(paused(exercise, tmp_path / "take.mid", [(6.0, 0.2)]))], capsys)
    assert got["restarts"] == [] and got["missed"] > 0 and got["extra"] > 0


CELLS = ("0", "5", "99.9", "100", "123.4", "999", "999.9")
"""Means, ms, the tables must line up for, either sign."""


def aligned(lines: list[str], labels: tuple[str, ...]) -> None:
    """Every right-aligned column of the table (its header first) ends where its label does."""
    header, *rows = lines
    for label in labels:
        end = header.index(label) + len(label)
        for row in rows:
            assert row[end - 1] != " " and (end == len(row) or row[end] == " "), (label, row)


@pytest.mark.parametrize("sign", [1, -1])
def test_the_mean_column_lines_up_up_to_999_ms(sign: int, tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    """``+100.0 ms`` is 9 characters: the columns after the mean moved one to the right in its row (until 7 Dec)."""
    exercise = tmp_path / "exercise.txt"
    exercise.write_text(groove(len(CELLS)), encoding="utf-8")
    path = paused(exercise, tmp_path / "take.mid", [])
    got = report([str(exercise), str(path)], capsys)
    means = [sign * float(cell) for cell in CELLS]
    for drum, mean in zip(got["drums"].values(), means, strict=False):
        drum["timing"]["mean_ms"] = mean
    for row, mean in zip(got["bars"], means, strict=True):
        row["mean_ms"] = mean
    lines = summary_lines(got, str(exercise), str(path))
    start = next(k for k, line in enumerate(lines) if line.startswith("drum "))
    drums = lines[start:start + 1 + len(got["drums"])]
    aligned(drums, ("written", "played", "too early/late", "missed", "extra", "other drum", "mean ms", "spread ms"))
    start = next(k for k, line in enumerate(lines) if line.startswith(" bar "))
    bars = lines[start:start + 1 + len(got["bars"])]
    aligned(bars, ("bar", "written", "played", "missed", "too early/late", "extra", "other drum", "mean ms",
                   "tempo bpm"))
    assert any(f"{sign * 999.9:+.1f} ms" in line for line in bars)


def test_a_take_lined_up_bars_in_has_no_count_in(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """16 bars at 1.004 of the tempo, no count-in, compared at the exercise's tempo (``--tempo-scale 1``; without
    it the take is compared at its own, tests/cli/test_compare_edges_and_drift.py): lined up three bars in (the
    drift), its first bars lay before the start, a steady hi-hat, kick and snare read "entered 0.2 beat early
    after the count-in" (until 7 Dec). A count-in repeats one sound (tests/cli/test_compare.py's side-sticks are
    still one)."""
    exercise = tmp_path / "long.txt"
    exercise.write_text(groove(16), encoding="utf-8")
    path = write_take(tmp_path / "take.mid", [(1.0 + t / 1.004, p, v) for t, p, v in written(exercise)])
    got = report([str(exercise), str(path), "--tempo-scale", "1"], capsys)
    assert got["offset_s"] > 2.0  # the first bars lie before the start: what the count-in was read from
    assert got["entry"] is None
    assert main([str(exercise), str(path), "--tempo-scale", "1"]) == 0
    assert "entered" not in capsys.readouterr().out
    count_in = [(3.0 - 0.5 * k, 37, 100) for k in range(4, 0, -1)]  # side-sticks a beat apart before it
    path = write_take(tmp_path / "counted.mid", count_in + [(3.0 + t, p, v) for t, p, v in written(exercise)])
    got = json.loads(run([str(exercise), str(path), "--json"], capsys)[1])
    assert got["entry"] is not None and got["entry"]["on_time"]
