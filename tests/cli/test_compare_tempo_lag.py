"""``batteur compare``: a take falling behind (running ahead) bar after bar is told so: its notes beyond the
tolerance count in their bar's mean, feel and tempo, the notes beyond the 150 ms reach are followed along the
take's lag (not "missed" with as many "extras"), and a line says the take stayed slower (faster) than written
after the tempo change; a take that jumps late once is not followed."""

from __future__ import annotations

from pathlib import Path

import pytest

from batteur.compare import bar_rows
from common.score.text import parse_text, read_score
from tests.cli.test_compare import PITCH, START, report, run, write_take

TEMPO_CHANGE = """\
tempo 90
meter 4/4
HH |x.x.x.x.|
SN |..x...x.|
BD |x...x...|
repeat 1
tempo 120
HH |x.x.x.x.|
SN |..x...x.|
BD |x...x...|
repeat 1
"""
"""Two bars of rock at 90 bpm, two at 120 (a teacher's exercise): quarter-note hi-hats, snare on 2 and 4, kick on 1
and 3; 32 notes, the change at 16/3 s."""
CHANGE_S = 60 / 90 * 8


def take_at(exercise: Path, tmp_path: Path, bpm: float) -> Path:
    """The exercise played exactly, its 120 bpm half at ``bpm`` from the change on (a 0.5 ms tick)."""
    notes = []
    for e in read_score(exercise).events:
        t = e.time if e.time < CHANGE_S - 1e-6 else CHANGE_S + (e.time - CHANGE_S) * 120 / bpm
        notes.append((round((START + t) * 2000) / 2000, PITCH[e.event.value], 100))
    return write_take(tmp_path / f"take{bpm:g}.mid", notes)


@pytest.fixture
def exercise(tmp_path: Path) -> Path:
    path = tmp_path / "tempochange.txt"
    path.write_text(TEMPO_CHANGE, encoding="utf-8")
    return path


@pytest.mark.parametrize(("bpm", "feel", "direction", "said", "early_late"),
                         [(110, "dragging", "behind", "falling behind", "late"),
                          (105, "dragging", "behind", "falling behind", "late"),
                          (130, "rushed", "ahead", "running ahead", "early")])
def test_a_tempo_change_played_off_tempo_is_told_as_falling_behind(
        bpm: float, feel: str, direction: str, said: str, early_late: str, exercise: Path, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    """The 120 bpm half played at 110 (130): 45 (38) ms more behind (ahead) each beat. Bar 3's late notes weigh in
    its mean, feel and tempo, bar 4's (182 to 318 ms late) are followed along the lag: no miss, no extra (until
    7 Dec bar 3 read +11 ms from its first four notes, not dragging, and bar 4 all missed with 8 extras);
    a line says the take stayed slower (faster) than written after the change, and its late notes are one line.
    At 105 a whole beat behind by the end: a note more than half a beat late is still the one it was played for,
    not one early for the next (the nearest)."""
    path = take_at(exercise, tmp_path, bpm)
    got = report([str(exercise), str(path)], capsys)
    assert (got["missed"], got["extra"], got["wrong_drum"], got["tempo"]) == (0, 0, 0, None)
    # running ahead, the take ends early: its last note was played for the last written one, no early stop
    assert got["take_stops"] is None and not any(m["after_take"] for m in got["misses"])
    assert got["played"] + got["off_tolerance"] == got["written"] == 32
    bars = {b["bar"]: b for b in got["bars"]}
    assert [bars[b]["feel"] for b in (1, 2, 3, 4)] == [None, None, feel, feel]
    assert (bars[4]["played"], bars[4]["missed"], bars[4]["off_tolerance"], bars[4]["extra"]) == (0, 0, 8, 0)
    assert bars[3]["played"] + bars[3]["off_tolerance"] == 8
    for b in (3, 4):  # every note of the bar in its tempo, the late ones too
        assert bars[b]["bpm"] == pytest.approx(bpm, abs=0.5) and bars[b]["written_bpm"] == 120
    lags = {3: sum(k * (60 / bpm - 0.5) for k in range(4)) / 4, 4: sum(k * (60 / bpm - 0.5) for k in range(4, 8)) / 4}
    for b in (3, 4):  # the median note is on time: bars 1 and 2 are, exactly
        assert bars[b]["mean_ms"] == pytest.approx(lags[b] * 1000, abs=1)
    [run_] = got["off_tempo"]
    assert (run_["direction"], run_["from_bar"], run_["to_bar"], run_["tempo_change"]) == (direction, 3, 4, True)
    assert (run_["bpm"], run_["written_bpm"], run_["written_before_bpm"]) == (pytest.approx(bpm, abs=0.5), 120, 90)
    assert run_["percent"] == pytest.approx((bpm / 120 - 1) * 100, abs=0.3)
    assert run_["lag_ms"] == pytest.approx(7 * (60 / bpm - 0.5) * 1000, abs=1) and run_["where"] == "bar 4, beat 4"
    assert got["drift"] is None
    _, out, _ = run([str(exercise), str(path)], capsys)
    assert (f"{said} in bars 3-4 after the tempo change (90 -> 120 bpm): played at about {bpm} bpm where 120 is "
            f"written ({abs(run_['percent']):.0f} % {'slower' if bpm < 120 else 'faster'} than written); "
            f"{abs(run_['lag_ms']):.0f} ms {early_late} by bar 4, beat 4") in out
    assert f"bar 3: {feel}" in out and f"bar 4: {feel}" in out
    assert not [line for line in out.splitlines() if line.startswith("bar ") and line.endswith((" missed", " extra"))]
    listing = [line for line in out.splitlines() if f"ms {early_late}" in line and line.startswith("bar ")]
    assert len(listing) == 1 and listing[0].startswith("bar 3, beat ")
    assert f"to bar 4, beat 4: {got['off_tolerance']} notes played" in listing[0]


def test_a_take_on_tempo_is_not_followed(exercise: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The exercise played as written: no note beyond the tolerance, no run off tempo; bar 4 played 200 ms late as
    a whole (a jump, not a tempo the take keeps: bar 3 is on time) is missed and extra, as before."""
    path = take_at(exercise, tmp_path, 120)
    got = report([str(exercise), str(path)], capsys)
    assert (got["played"], got["off_tolerance"], got["off_tempo"]) == (32, 0, [])
    notes = [(e.time + (0.2 if e.time >= CHANGE_S + 2 - 1e-6 else 0.0), PITCH[e.event.value], 100)
             for e in read_score(exercise).events]
    jumped = write_take(tmp_path / "jump.mid", [(START + t, p, v) for t, p, v in notes])
    got = report([str(exercise), str(jumped), "--offset", str(START)], capsys)
    assert (got["played"], got["off_tolerance"], got["missed"], got["extra"]) == (24, 0, 8, 8)
    assert got["off_tempo"] == []


def test_a_bar_s_notes_beyond_the_tolerance_weigh_in_its_mean_feel_and_tempo() -> None:
    """Four quarter notes at 120 bpm, the last two 90 and 135 ms late: the bar's mean is all four's (+56 ms,
    dragging) and its tempo theirs (109 bpm); ``played`` still counts the two within the tolerance (until the day
    after 7 Dec the bar read 0 ms, not dragging, 120 bpm)."""
    score = parse_text("tempo 120\nmeter 4/4\nSN |x...x...x...x...|\n")
    written = [(t, t) for t in (0.0, 0.5, 1.0, 1.5)]
    late = [(2, 1.09, 0.09), (3, 1.635, 0.135)]
    [row] = bar_rows(score, written, [(0, 0.0, 0.0), (1, 0.5, 0.0)], [], [2, 3], [], [], 0.05, late)
    assert (row["played"], row["off_tolerance"], row["feel"]) == (2, 2, "dragging")
    assert row["mean_ms"] == pytest.approx(56.2, abs=0.1)
    # the least-squares slope through 0, 0.5, 1.09 and 1.635 s: 0.5495 s a quarter note
    assert row["bpm"] == pytest.approx(109.2, abs=0.05) and row["written_bpm"] == 120
