"""The benchmark's account of lost onsets (``recogniser_bench.py --losses``): its bounds must mean what they say,
since the choice of what to try next rests on them."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mir_eval")
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))

import recogniser_bench as bench  # noqa: E402

from services.recogniser.training.render import Hit  # noqa: E402


def test_ideal_grouping_joins_every_strike_near_a_reference_onset() -> None:
    ref = np.array([1.0, 1.03, 2.0])  # two onsets 30 ms apart, one alone
    # four strikes around the pair (one of them 45 ms late), one at 2.0 s, one far from everything
    est = np.array([0.99, 1.005, 1.028, 1.075, 2.001, 3.0])
    assert bench.ideal_grouping(ref, est) == (3, 3, 4)  # every reference found; only the far strike is extra
    # decoded as given, the same strikes count extra onsets for the late one and the far one
    assert bench.onset_scores(ref, est) == (3, 3, 6)


def test_exact_times_moves_only_strikes_of_the_right_class_close_enough() -> None:
    hits = [Hit(1.0, 0, 100), Hit(1.02, 1, 90)]
    events = [(1.004, 0), (1.012, 1), (1.05, 0), (1.0, 2)]
    moved = bench.exact_times(hits, events, within=0.015)
    assert moved == [(1.0, 0), (1.02, 1), (1.05, 0), (1.0, 2)]  # 50 ms away, or no such class struck: unchanged


def test_chord_times_follow_the_transcribers_grouping() -> None:
    events = [(1.0, 0), (1.015, 2), (1.03, 1)]
    assert bench.chord_times(events, 0.02).tolist() == [1.0, 1.0, 1.03]
    assert bench.chord_times(events, 0.0).tolist() == [1.0, 1.015, 1.03]


def test_onset_merge_sets_which_close_strikes_are_one_reference_onset(capsys: pytest.CaptureFixture[str]) -> None:
    # a flam: snare 25 ms after a hi-hat, transcribed as one strike; then a lone kick found
    hits = [Hit(1.0, 2, 90), Hit(1.025, 1, 100), Hit(2.0, 0, 100)]
    found = [(1.0, 2), (2.0, 0)]

    def onsets_row(merge_s: float) -> list[str]:
        bench.table([(hits, found)], merge_s)
        row = next(line for line in capsys.readouterr().out.splitlines() if line.startswith("onsets "))
        return row.split()

    assert onsets_row(0.02)[1:3] == ["3", "|"] and onsets_row(0.02)[3] == "0.800"  # two onsets for the flam
    assert onsets_row(0.03)[1:4] == ["2", "|", "1.000"]  # the flam is one onset, found
