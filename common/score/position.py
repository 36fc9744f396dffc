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
    if j == len(bars) - 1:  # the last bar; after it, bars as long go on
        length = last_bar_length(score)
        more = int((beat + 1e-9) // length)
        j, beat = j + more, beat - more * length
    return BarBeat(j, max(beat, 0.0), 60.0 / spacing)


def last_bar_length(score: Score) -> float:
    """Beats of the last bar of ``score`` (which has ``bar_beats``), and of each bar after it: to the score's last
    beat; a reader whose score ends inside a bar, or between two beats, puts a last start at or past the end: then
    the last two starts give the length (one start: :data:`DEFAULT_BEATS_PER_BAR`). :func:`bar_beat` counts bars
    past the last start so, and ``common.score.bars`` lays them so."""
    bars = score.bar_beats
    j = len(bars) - 1
    length = len(score.beats) - 1 - float(bars[j])
    if length <= 0:
        length = float(bars[j] - bars[j - 1]) if j > 0 else float(DEFAULT_BEATS_PER_BAR)
    return length


def seconds_at_beat(score: Score, beat: float) -> float:
    """Score seconds at ``beat`` (beats from the first, fractional): :func:`bar_beat`'s position the other way;
    past the last beat its spacing goes on, as there. The score has at least two beats."""
    beats = np.asarray(score.beats, dtype=float)
    last = len(beats) - 1
    if beat <= last:
        return float(np.interp(beat, np.arange(len(beats)), beats))
    return float(beats[-1] + (beat - last) * (beats[-1] - beats[-2]))


def bar_unit(score: Score, bar: int) -> float:
    """The beat bar ``bar`` (from 0, as :func:`bar_beat` numbers them) is counted in, quarter notes: its meter's
    1/D note (``Score.bar_units``: 0.5 in x/8, 1 in x/4); bars past the last start as the last; quarter notes for a
    score that gives none."""
    units = score.bar_units
    if not len(units) or len(units) != len(score.bar_beats):
        return 1.0
    return float(units[min(max(bar, 0), len(units) - 1)])


def pickup(score: Score) -> tuple[float, float] | None:
    """(beats of the pick-up, beats of the bar after it) when the score's first bar is shorter than its second (a
    text score's ``meter 1/4`` then ``meter 4/4``, a MIDI file's first time signature), else None."""
    bars = np.asarray(score.bar_beats, dtype=float)
    if len(bars) < 2 or bars[0] > 1e-9:
        return None
    if score.end_beat is not None and bars[1] >= score.end_beat - 1e-9:
        # one bar: the start after it is where the score ends (a text score's bar of 1/16, shorter than the beat
        # its beats are padded to, was a pick-up of its own, "bar 0, beat 3", until 7 Dec)
        return None
    # the second bar's length: to the third start, else (the last bar) to the score's last beat
    second = float(bars[2] - bars[1]) if len(bars) > 2 else float(len(score.beats) - 1 - bars[1])
    first = float(bars[1] - bars[0])
    return (first, second) if 0 < first < second - 1e-9 else None


def counted_bar_beat(score: Score, seconds: float) -> tuple[int, float, float] | None:
    """(bar, beat from 1 (fractional), the beat's length s) at score time ``seconds`` (as written), counted as a
    musician counts: bars from 1 (after a pick-up, :func:`pickup`, the first full bar is bar 1 and the pick-up bar
    0, its beats counted as the end of a full bar), beats in the meter's 1/D note (:func:`bar_unit`: eighths in 6/8
    and 7/8, as a DAW counts), their length from the written tempo there; None before the first beat (as
    :func:`bar_beat`). ``batteur compare`` numbers its bars so, and the physics score player's logs say where a
    stop, pause, re-plan or end falls so."""
    where = bar_beat(score, seconds)
    if where is None:
        return None
    short = pickup(score)
    # a pick-up's beats are counted as the end of the full bar after it (its unit too: 1/4 before 6/8)
    unit = bar_unit(score, 1 if short is not None and where.bar == 0 else where.bar)
    spacing = 60.0 / where.tempo_bpm * unit
    beat = where.beat / unit + 1
    if short is None:
        return where.bar + 1, beat, spacing
    return where.bar, beat + ((short[1] - short[0]) / unit if where.bar == 0 else 0.0), spacing
