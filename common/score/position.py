"""Where a score is: bar, beat within the bar and tempo at a score time.

What the view's status panel shows while a score plays (``/batteur/graphics/score_position``). Bars come from the
score's ``bar_beats`` (the MIDI file's time signatures, the text format's ``meter``); a score without them (built
from live notes) is counted in bars of :data:`DEFAULT_BEATS_PER_BAR` beats.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from common.score.events import Score

DEFAULT_BEATS_PER_BAR = 4
"""Beats per bar of a score that gives none."""


@dataclass(frozen=True)
class BarBeat:
    """A score position: ``bar`` from 0, ``beat`` within the bar from 0 (fractional), ``tempo_bpm`` as written
    (beats per minute between the two beats around the position)."""

    bar: int
    beat: float
    tempo_bpm: float


def bar_beat(score: Score, seconds: float) -> BarBeat | None:
    """The bar and beat at score time ``seconds`` (as written, from the score's start).

    Past the last beat the last beat's spacing goes on; before the first, None (as for a score with fewer than
    two beats, which gives no tempo).
    """
    beats = score.beats
    if len(beats) < 2 or not math.isfinite(seconds) or seconds < beats[0]:
        return None
    k = min(int(np.searchsorted(beats, seconds, side="right")) - 1, len(beats) - 2)
    spacing = float(beats[k + 1] - beats[k])
    if spacing <= 0:
        return None
    position = k + (seconds - float(beats[k])) / spacing  # beats from the first
    bars = score.bar_beats
    if not len(bars) or position < bars[0]:
        bar = int(position // DEFAULT_BEATS_PER_BAR)
        return BarBeat(bar, max(position - bar * DEFAULT_BEATS_PER_BAR, 0.0), 60.0 / spacing)
    j = int(np.searchsorted(bars, position + 1e-9, side="right")) - 1
    beat = position - float(bars[j])
    if j == len(bars) - 1:  # the last bar ends with the score's beats; after them, bars as long go on (a reader
        # whose score ends inside a bar, or between two beats, puts a last start past the end: the last two starts
        # give the length)
        length = len(beats) - 1 - float(bars[j])
        if length <= 0:
            length = float(bars[j] - bars[j - 1]) if j > 0 else DEFAULT_BEATS_PER_BAR
        more = int((beat + 1e-9) // length)
        j, beat = j + more, beat - more * length
    return BarBeat(j, max(beat, 0.0), 60.0 / spacing)
