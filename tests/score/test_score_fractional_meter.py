"""A fractional meter (`meter 2.5/4`: bars of two and a half beats): the last bar is as long as the meter says,
though the score's beats stop at its last whole beat."""

from __future__ import annotations

import pytest

from common.score.position import bar_beat
from common.score.text import parse_text


def _bar_and_beat(text: str, seconds: float) -> tuple[int, float]:
    where = bar_beat(parse_text("tempo 60\n" + text), seconds)  # a beat a second
    assert where is not None
    return where.bar, round(where.beat, 6)


@pytest.mark.parametrize(("text", "expected"), [
    # three bars of 2.5 beats end at beat 7.5, the beats at 7: the last bar (from 5) was 2 beats long, so beat 7.25
    # read as bar 3 and every bar past the end as 2 beats
    ("meter 2.5/4\nSN |x....|x....|x....|\n", {6: (2, 1), 7.25: (2, 2.25), 7.5: (3, 0), 8.75: (3, 1.25), 10: (4, 0)}),
    # a bar of 4 then one of 2.5, ending at 6.5
    ("meter 4/4\nBD |x...|\nmeter 2.5/4\nSN |x....|\n", {6.25: (1, 2.25), 6.5: (2, 0), 9: (3, 0)}),
    # `at` notes only: bars of the meter through the one holding the last note (ends at 7.5)
    ("meter 2.5/4\nat 0 BD\nat 5.5 SN\n", {7.25: (2, 2.25), 7.5: (3, 0), 8: (3, 0.5)}),
])
def test_the_last_bar_of_a_fractional_meter_is_a_whole_bar(text: str, expected: dict[float, tuple[int, float]]) -> None:
    assert {t: _bar_and_beat(text, t) for t in expected} == expected


def test_bars_of_a_fractional_meter_ending_on_a_whole_beat_are_as_they_were() -> None:
    score = parse_text("tempo 60\nmeter 2.5/4\nSN |x....|x....|\n")  # ends at beat 5
    assert score.bar_beats.tolist() == [0, 2.5] and score.beats.tolist() == [0, 1, 2, 3, 4, 5]
