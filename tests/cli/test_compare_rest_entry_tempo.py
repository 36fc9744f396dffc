"""``batteur compare``: an entry late after a written rest in a take also off tempo still gets its tempo verdict
(the notes only near their written time are no evidence against the tempo: until 7 Dec 8 bars 7 % slow with bar 5
entered 0.5 s late read "14 of 78 played, 56 too early or late" and no tempo), and an entry note a few ms early is
still placed in its bar after the rest ("after the rest (bar 3)" for a rest over bars 3-4, "0.99 beats", until
7 Dec)."""

from __future__ import annotations

import random
from pathlib import Path

import pytest

from tests.cli.test_compare import report, run, write_take, written
from tests.cli.test_compare_rest_entry import exercise

START = 2.0


def take(exercise_path: Path, path: Path, late: float, ratio: float = 1.0, jitter: float = 0.0) -> Path:
    """The exercise played from :data:`START` at ``ratio`` times its tempo, its notes from written 8 s (bar 5) on
    ``late`` written s later, each moved by up to ``jitter`` s (seeded), on the MIDI file's 0.5 ms ticks."""
    rnd = random.Random(1)
    return write_take(path, [(round((START + (t + (late if t >= 8.0 - 1e-9 else 0.0)) / ratio
                                     + rnd.uniform(-jitter, jitter)) * 2000) / 2000, p, v)
                             for t, p, v in written(exercise_path)])


def test_a_take_off_tempo_entering_late_after_a_rest_keeps_its_tempo(tmp_path: Path,
                                                                    capsys: pytest.CaptureFixture[str]) -> None:
    """8 bars, bars 3-4 rest, bar 5 entered a beat late, the whole take 7 % slow (0.93): compared at 0.93, bars
    1-2 on time, the entry said and bars 5-8 told late by it."""
    path = exercise(tmp_path / "rest.txt", [True, True, False, False, True, True, True, True])
    played = take(path, tmp_path / "take.mid", 0.5, 0.93)
    got = report([str(path), str(played)], capsys)
    assert got["tempo_scale_found"] is True
    assert got["tempo"]["ratio"] == pytest.approx(0.93, abs=0.005)
    assert (got["played"], got["off_tolerance"], got["missed"], got["extra"]) == (26, 52, 0, 0)
    assert [(e["bar"], e["rest"]) for e in got["rest_entries"]] == [(5, "bars 3-4")]
    assert got["rest_entries"][0]["late_beats"] == pytest.approx(1.0, abs=0.01)
    _, out, _ = run([str(path), str(played)], capsys)
    assert "compared at the take's tempo (--tempo-scale 0.93)" in out


@pytest.mark.parametrize("by", [0.5, -0.5, 0.2, 2.0])
def test_an_entry_note_a_few_ms_off_is_in_its_bar_after_the_rest(by: float, tmp_path: Path,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    """Six bars, bars 3-4 rest, bar 5 ``by`` s off, every note within 6 ms of its time: the rest is bars 3-4,
    the entry bar 5, beat 1, said in whole beats where it is a whole beat off."""
    path = exercise(tmp_path / "rest.txt", [True, True, False, False, True, True])
    played = take(path, tmp_path / "take.mid", by, jitter=0.006)
    got = report([str(path), str(played)], capsys)
    assert [(e["bar"], e["beat"], e["rest"]) for e in got["rest_entries"]] == [(5, 1.0, "bars 3-4")]
    assert got["rest_entries"][0]["late_beats"] == pytest.approx(by / 0.5, abs=0.03)
    _, out, _ = run([str(path), str(played)], capsys)
    beats = round(abs(by) / 0.5, 1)
    how = "late" if by > 0 else "early"
    assert (f"bar 5: came in {abs(by):.1f} s {how} ({beats:g} beat{'' if beats == 1 else 's'}) after the rest "
            "(bars 3-4)") in out
