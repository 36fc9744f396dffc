"""``batteur render --bars A-B``: only those bars of a long score are planned and simulated, on the score's clock
shifted so that bar A starts at score time 0; report.json's ``bars`` says the part, and ``batteur evaluate DIR``
judges the render against those bars. A range the score does not have, or one ending before it starts, is one line
and exit status 2, before anything is simulated. Until 8 Dec a 10-minute file could only be rendered whole."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import mido
import pytest

from batteur import render
from batteur.evaluate import evaluate_render_dir
from batteur.impact_log import read_impacts_csv
from batteur.score_part import EARLY_S, bar_part
from common.score.bars import counted_bars
from common.score.position import counted_bar_beat
from common.score.summary import score_length
from common.score.text import read_score

ROOT = Path(__file__).resolve().parents[2]
FOUR_BARS = """tempo 120
meter 4/4
HH |x.x.x.x.|........|........|........|
SN |........|x...x...|........|........|
BD |........|........|x.x.x.x.|........|
T1 |........|........|........|x.x.x.x.|
"""
"""Each bar its own drum, bars 2 s long: bar 2 the snare, bar 3 the kick."""
METERS = """tempo 120
meter 3/4
HH |x.x.x.|x.x.x.|
meter 6/8
SN |x..x..|x..x..|
meter 7/8
BD |x.x.x..|x.x.x..|
meter 4/4
HH |x.x.x.x.|
"""
"""Meters change every two bars: 3/4 (1.5 s a bar), 6/8 (1.5 s), 7/8 (1.75 s), 4/4 (2 s)."""


def _score(tmp_path: Path, text: str, name: str = "song.txt") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_a_part_renders_only_its_bars_on_its_own_clock(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    score = _score(tmp_path, FOUR_BARS)
    out = tmp_path / "out"
    assert render.main([str(score), "-o", str(out), "--quiet", "--bars", "2-3"]) == 0
    said = capsys.readouterr().out
    assert "bars 2 to 3 of the score (2 bars, 8 beats)" in said
    assert "score time 0 (bar 2, beat 1) is at" in said
    report = json.loads((out / "report.json").read_text())
    assert report["bars"] == {"first": 2, "last": 3, "start_s": 2.0, "end_s": 6.0}
    assert report["notes"] == 6 and (report["score_bars"], report["score_beats"]) == (2, 8.0)
    impacts = read_impacts_csv(out / "impacts.csv")
    assert sorted({i.instrument for i in impacts}) == ["kick", "snare"]  # no hi-hat (bar 1), no tom (bar 4)
    part_times = sorted(i.time - report["score_offset_s"] for i in impacts)
    expected = [0.0, 1.0, 2.0, 2.5, 3.0, 3.5]  # bar 2's snares at its beats 1 and 3, bar 3's kicks on every beat
    assert part_times == pytest.approx(expected, abs=0.025)
    result = evaluate_render_dir(out / "score.txt", out)  # judged against bars 2-3, on the part's clock
    assert result.matched["25ms"] == result.notes == 6 and result.spurious == 0 and not result.missed


def test_a_part_across_meter_changes_holds_the_notes_and_bar_lines_of_its_bars(tmp_path: Path) -> None:
    score = read_score(_score(tmp_path, METERS))
    assert counted_bars(score) == (1, 7)
    part, start, end = bar_part(score, (3, 6), "meters.txt")  # the 6/8 bars and the 7/8 ones
    assert (start, end) == pytest.approx((3.0, 9.5))
    assert score_length(part) == (pytest.approx(13.0), 4)
    assert [e.event.value for e in part.events] == ["SNARE"] * 4 + ["BASS"] * 6
    assert part.events[0].time == pytest.approx(0.0)
    assert [counted_bar_beat(score, e.time + start)[0] for e in part.events] == [3, 3, 4, 4, 5, 5, 5, 6, 6, 6]
    assert [counted_bar_beat(part, e.time)[0] for e in part.events] == [1, 1, 2, 2, 3, 3, 3, 4, 4, 4]  # bar 3 is 1
    assert list(part.bar_units) == [0.5, 0.5, 0.5, 0.5]  # counted in eighths, as in the score


def test_a_note_played_just_before_the_bar_line_is_the_bars(tmp_path: Path) -> None:
    score = read_score(_score(tmp_path, FOUR_BARS))
    early = score.events[4]  # the first snare, bar 2's downbeat, played 30 ms early (a drummer ahead of the beat)
    assert early.event.value == "SNARE"
    score.events[4] = dataclasses.replace(early, time=early.time - 0.03)
    part, _, _ = bar_part(score, (2, 2), "song.txt")
    assert part.events[0].time == pytest.approx(-0.03) and 0.03 < EARLY_S
    bar_1, _, _ = bar_part(score, (1, 1), "song.txt")
    assert all(e.event.value == "HIHATCLOSED" for e in bar_1.events)  # not in bar 1 any more


@pytest.mark.parametrize(("bars", "says"), [
    ("5-6", "--bars 5-6: song.txt has bars 1 to 4 (`python -m common.score song.txt` lists them)"),
    ("0", "--bars 0: song.txt has bars 1 to 4"),  # one bar as given: "--bars 0-0" until 8 Dec
    ("5", "--bars 5: song.txt has bars 1 to 4"),
    ("3-2", "--bars 3-2: the range ends (bar 2) before it starts (bar 3): give 2-3"),
    ("two", "--bars 'two': a bar or a range of bars as `python -m common.score SCORE` counts them"),
])
def test_bars_the_score_does_not_have_are_one_line_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                          bars: str, says: str) -> None:
    score = _score(tmp_path, FOUR_BARS)
    out = tmp_path / "out"
    assert render.main([str(score), "-o", str(out), "--quiet", "--bars", bars]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"batteur render: error: {says}"), err
    assert not out.exists()  # refused before anything was written


def _midi(path: Path, numerator: int, denominator: int, bpm: float, ticks: list[int], end: int) -> Path:
    """One drum track: a snare at each of ``ticks`` (480 a quarter note), the file ending at tick ``end``."""
    track = mido.MidiTrack([mido.MetaMessage("time_signature", numerator=numerator, denominator=denominator),
                            mido.MetaMessage("set_tempo", tempo=mido.bpm2tempo(bpm))])
    last = 0
    for tick in ticks:
        track.append(mido.Message("note_on", channel=9, note=38, velocity=100, time=tick - last))
        track.append(mido.Message("note_off", channel=9, note=38, velocity=0, time=60))
        last = tick + 60
    track.append(mido.MetaMessage("end_of_track", time=max(end - last, 0)))
    mid = mido.MidiFile(type=1, ticks_per_beat=480)
    mid.tracks.append(track)
    mid.save(str(path))
    return path


def test_fast_notes_at_a_bar_line_stay_in_their_bar(tmp_path: Path) -> None:
    """Two bars of 32nd notes at 180 bpm (42 ms apart): each bar's part holds its 32 notes, from its bar line, and
    the two bars together all 64 (until 8 Dec a note within 50 ms before a bar line was the next bar's: bar 1 had
    31, bar 2 a pick-up at -0.042 s, and bars 1-2 lost the score's last note)."""
    score = read_score(_midi(tmp_path / "E_32nds_180.mid", 4, 4, 180, [k * 60 for k in range(64)], 8 * 480))
    for bars, count in (((1, 1), 32), ((2, 2), 32), ((1, 2), 64)):
        part, _, _ = bar_part(score, bars, "E_32nds_180.mid")
        assert len(part.events) == count, bars
        assert part.events[0].time == pytest.approx(0.0, abs=1e-9), bars


def test_a_part_starting_inside_a_beat_counts_its_beats_from_its_bar_line(tmp_path: Path) -> None:
    """Bar 2 of a 7/8 file starts half a beat into beat 4: report.json's score_beats is its 3.5 quarter notes (4.0
    until 8 Dec, counted from the beat before its bar line)."""
    score = read_score(_midi(tmp_path / "B_7_8.mid", 7, 8, 120, [k * 240 for k in range(28)], 14 * 480))
    for bars, length in (((2, 2), (3.5, 1)), ((2, 3), (7.0, 2)), ((1, 4), (14.0, 4))):
        assert score_length(bar_part(score, bars, "B_7_8.mid")[0]) == length, bars


def test_one_bar_is_said_bar_n_not_bars_n_to_n() -> None:
    report = {"score_beats": 3.0, "score_bars": 1, "bars": {"first": 14, "last": 14}}
    assert render.bars_words(report) == "; bar 14 of the score (1 bar, 3 beats)"
    report["bars"] = {"first": 2, "last": 3}
    assert render.bars_words(report) == "; bars 2 to 3 of the score (1 bar, 3 beats)"
