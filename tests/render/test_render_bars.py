"""``batteur render --bars A-B``: only those bars of a long score are planned and simulated, on the score's clock
shifted so that bar A starts at score time 0; report.json's ``bars`` says the part, and ``batteur evaluate DIR``
judges the render against those bars. A range the score does not have, or one ending before it starts, is one line
and exit status 2, before anything is simulated. Until 8 Dec a 10-minute file could only be rendered whole."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

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
    ("0", "--bars 0-0: song.txt has bars 1 to 4"),
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
