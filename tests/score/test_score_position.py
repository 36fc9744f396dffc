"""Bars and beats of a score (common/score/position.py): what the view's status panel shows while it plays."""

from __future__ import annotations

import numpy as np
import pytest

from common.score.midi import read_midi
from common.score.position import bar_beat
from common.score.text import parse_text
from tests.score.midi_files import drum_midi


def _kicks(signatures: list[tuple[int, int, int]], bars_ticks: int, ticks_per_beat: int = 480) -> bytes:
    """One drum track at 120 bpm: (tick, numerator, denominator) time signatures, a kick at tick 0 and at
    ``bars_ticks``."""
    return drum_midi(signatures, [0, bars_ticks], tpb=ticks_per_beat, note=36)


def test_text_score_bars_follow_its_blocks_meter_repeats_and_rests() -> None:
    score = parse_text("tempo 120\nmeter 4/4\nBD |x...|x...|\n\nrepeat 1\nmeter 3/4\nSN |x..|\nrest 4\nBD |x...|\n")
    # two 4/4 bars, repeated, a 3/4 bar, a 4-beat rest in 3/4 (a bar and a bar cut short), a bar of 3
    assert score.bar_beats.tolist() == [0, 4, 8, 12, 16, 19, 22, 23]


def test_midi_bars_follow_its_time_signatures() -> None:
    tpb = 480
    score = read_midi(_kicks([(0, 4, 4), (2 * 4 * tpb, 6, 8)], 4 * 4 * tpb, tpb))
    # two bars of 4/4, then 6/8 bars of three quarter-note beats
    assert score.bar_beats[:5].tolist() == [0, 4, 8, 11, 14]


def test_midi_without_time_signature_counts_bars_of_four() -> None:
    score = read_midi(_kicks([], 3 * 4 * 480))
    assert score.bar_beats[:3].tolist() == [0, 4, 8]


def test_bar_beat_of_a_score_time() -> None:
    score = parse_text("tempo 100\nmeter 3/4\nBD |x..|x..|x..|\n")  # a beat every 0.6 s, bars of 3
    where = bar_beat(score, 2.4)  # beat 4 from the start: bar 1, beat 1
    assert where is not None
    assert (where.bar, where.beat, where.tempo_bpm) == (1, pytest.approx(1.0), pytest.approx(100.0))
    half = bar_beat(score, 0.3)
    assert half is not None and (half.bar, half.beat) == (0, pytest.approx(0.5))


def test_past_the_last_bar_bars_as_long_go_on() -> None:
    score = parse_text("tempo 120\nmeter 3/4\nBD |x..|x..|\n")  # bars at beats 0 and 3, the score ends at 6
    where = bar_beat(score, 3.75)  # beat 7.5
    assert where is not None and (where.bar, where.beat) == (2, pytest.approx(1.5))


def test_bar_beat_without_bars_counts_four_and_without_beats_is_none() -> None:
    score = parse_text("tempo 120\nBD |x...|x...|\n")
    score.bar_beats = np.zeros(0)
    where = bar_beat(score, 2.75)  # beat 5.5
    assert where is not None and (where.bar, where.beat) == (1, pytest.approx(1.5))
    score.beats = np.zeros(0)
    assert bar_beat(score, 1.0) is None
    assert bar_beat(parse_text("BD |x...|\n"), -0.1) is None
