"""Where a text score ends: bars past a closing rest shorter than a bar, and `at` notes placed after its last block
(what the view's position and the report show there)."""

from __future__ import annotations

import pytest

from common.score.events import Score, ScoreError
from common.score.position import bar_beat
from common.score.text import parse_text


def _bar_and_beat(score: Score, seconds: float) -> tuple[int, float]:
    where = bar_beat(score, seconds)
    assert where is not None
    return where.bar, round(where.beat, 6)


@pytest.mark.parametrize(("text", "expected"), [
    # a 4/4 bar, a one-beat rest: bar 1 is that beat; past the end, bars of 4 from where the score ends (as a block
    # written there would start), not bars of 1
    ("meter 4/4\nBD |x...|\nrest 1\n", {4.5: (1, 0.5), 5: (2, 0), 6: (2, 1), 8: (2, 3), 9: (3, 0), 14: (4, 1)}),
    # a rest of a bar and a half in 3/4 (bars at 3 and 6, the second cut short at 7.5): bars of 3 past it
    ("meter 3/4\nSN |x..|\nrest 4.5\n", {6.5: (2, 0.5), 7.5: (3, 0), 9: (3, 1.5), 10.5: (4, 0), 12: (4, 1.5)}),
    # a short rest after a meter change: bars of the meter in force
    ("meter 4/4\nBD |x...|\nmeter 3/4\nrest 2\n", {5: (1, 1), 6: (2, 0), 8: (2, 2), 9: (3, 0)}),
])
def test_bars_past_a_closing_short_rest_are_whole_bars(text: str, expected: dict[float, tuple[int, float]]) -> None:
    score = parse_text("tempo 60\n" + text)  # a beat a second
    assert {beat: _bar_and_beat(score, beat) for beat in expected} == expected


def test_a_score_ending_on_a_bar_line_counts_on_as_it_did() -> None:
    score = parse_text("tempo 60\nmeter 3/4\nBD |x..|x..|\nrest 3\n")
    assert score.bar_beats.tolist() == [0, 3, 6] and len(score.beats) == 10
    assert _bar_and_beat(score, 10) == (3, 1)


def test_at_notes_after_the_last_block_are_counted_at_the_last_tempo() -> None:
    # the block at 120 bpm ends at 2 s; the snare is 6 beats later at 60 bpm: beat 10, bar 2 (bars of 4), beat 2.
    # The beats stopped at the block's end: the position was counted at 120 bpm, bar 4
    score = parse_text("tempo 120\nmeter 4/4\nBD |x...|\ntempo 60\nat 6 SN\n")
    snare = score.events[-1].time
    assert snare == pytest.approx(8.0)
    assert score.beats[-1] >= snare  # the head nods over it too
    where = bar_beat(score, snare)
    assert where is not None and (where.bar, round(where.beat, 6), where.tempo_bpm) == (2, 2, pytest.approx(60.0))
    assert score.bar_beats.tolist() == [0, 4, 8]


def test_at_notes_after_the_last_block_are_in_bars_of_the_meter_from_its_end() -> None:
    score = parse_text("tempo 60\nmeter 4/4\nBD |x...|\nmeter 3/4\nat 4 SN 0.5\nat 1.5 HH\n")
    assert [e.time for e in score.events] == [0.0, 5.5, 8.0]
    assert score.bar_beats.tolist() == [0, 4, 7]  # bars of 3 after the 4/4 block, through the one holding beat 8
    assert score.beats.tolist() == list(range(11))
    assert _bar_and_beat(score, 5.5) == (1, 1.5) and _bar_and_beat(score, 8) == (2, 1)


def test_at_notes_within_the_score_change_no_bar() -> None:
    plain = parse_text("tempo 90\nBD |x...|x...|\nrest 2\n")
    noted = parse_text("tempo 90\nat 5 SN\nBD |x...|x...|\nrest 2\nat -1 HH\n")
    assert noted.bar_beats.tolist() == plain.bar_beats.tolist()
    assert noted.beats.tolist() == plain.beats.tolist()


def test_an_at_note_whose_bar_would_outlast_a_score_is_refused_naming_its_line() -> None:
    # its bar of a million beats (5.8 days at 120 bpm) was filled with beats: seconds of work, and more for more
    with pytest.raises(ScoreError, match=r"line 2: the score would last 138.9 h, longer than the 24 h"):
        parse_text("meter 1000000/4\nat 0 BD\n")
