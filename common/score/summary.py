"""A score's length, tempo and time signatures as a DAW shows them: ``python -m common.score``'s header and the
score length ``batteur render`` reports.

Worked out from what every reader fills in (:class:`common.score.events.Score`): ``beats`` (each quarter note's
time), ``bar_beats`` and ``bar_units`` (where the bars start, the note each is counted in) and ``end_beat``. The
tempo is read beat by beat: a change inside a beat shows as that beat's average, then the new tempo from the next.
"""

from __future__ import annotations

import numpy as np

from common.score.events import Score
from common.score.position import seconds_at_beat

LISTED_CHANGES = 6
"""The most tempo or time signature changes the header lists one by one (more: counted, with their range)."""
TEMPO_TOLERANCE = 1e-6
"""Relative difference of two beats' tempi below which they are one tempo (the readers' rounding)."""


def score_length(score: Score) -> tuple[float, int] | None:
    """(beats, bars) of ``score`` up to its end (:attr:`Score.end_beat`: a text score's last bar, a MIDI file's end
    of track): beats in quarter notes to a hundredth, the bars starting before the end; None when its reader does
    not know its end (a live or performed score)."""
    if score.end_beat is None:
        return None
    end = round(score.end_beat, 2)
    return end, int(np.count_nonzero(np.asarray(score.bar_beats) < end - 1e-9))


def _bars(score: Score) -> list[tuple[float, float, float]]:
    """(start, length, counted note) of each bar up to the score's end, beats: a bar's length runs to the next start
    (the last one to the score's end when no start follows). A last bar ending where the score does, shorter than
    the one before it in the same counted note, is one the end cuts short (a text score closing on a half-bar rest):
    it keeps that bar's length, as a DAW's bar ruler does (a MIDI file's last bar runs past its end of track)."""
    starts = np.asarray(score.bar_beats, dtype=float)
    units = np.asarray(score.bar_units, dtype=float)
    counted = len(starts) if score.end_beat is None else int(np.count_nonzero(starts < score.end_beat - 1e-9))
    bars: list[tuple[float, float, float]] = []
    for k in range(counted):
        if k + 1 < len(starts):
            length = float(starts[k + 1] - starts[k])
        elif score.end_beat is not None:
            length = float(score.end_beat - starts[k])
        else:
            break
        unit = float(units[k]) if k < len(units) and units[k] > 0 else 1.0
        bars.append((float(starts[k]), length, unit))
    if (len(bars) >= 2 and score.end_beat is not None and abs(sum(bars[-1][:2]) - score.end_beat) < 1e-9
            and bars[-1][2] == bars[-2][2] and bars[-1][1] < bars[-2][1] - 1e-9):
        bars[-1] = (bars[-1][0], bars[-2][1], bars[-1][2])
    return bars


def last_bar_end(score: Score) -> float | None:
    """Where the bar holding the score's end ends, beats: a MIDI file's end of track inside a bar (as most are,
    just after the last note) counts to the end of that bar, as a DAW's bar ruler; None when the end is not known."""
    if score.end_beat is None:
        return None
    bars = _bars(score)
    return max(bars[-1][0] + bars[-1][1], float(score.end_beat)) if bars else float(score.end_beat)


def beat_seconds(score: Score, beat: float) -> float | None:
    """Score time (seconds) of ``beat`` (quarter notes from the start): between two beats in proportion, past the
    last one at the last beat's tempo; None for a score with fewer than two beats (no tempo)."""
    if len(score.beats) < 2:
        return None
    return seconds_at_beat(score, beat)


def tempo_changes(score: Score) -> list[tuple[float, float]]:
    """(beat, beats a minute) where the tempo changes, beat by beat, the first at beat 0 (the start tempo); empty
    for a score with fewer than two beats."""
    beats = np.asarray(score.beats, dtype=float)
    if len(beats) < 2:
        return []
    bpm = 60.0 / np.diff(beats)
    changed = np.flatnonzero(np.abs(np.diff(bpm)) > TEMPO_TOLERANCE * bpm[1:]) + 1
    return [(0.0, float(bpm[0]))] + [(float(k), float(bpm[k])) for k in changed]


def _number(value: float) -> str:
    """A meter's count: ``4``, ``2.5``."""
    return f"{round(value, 6):g}"


def meter_changes(score: Score) -> list[tuple[float, str]]:
    """(beat, ``N/D``) where the bars' time signature changes, the first at the first bar: each bar's length in
    its counted note (``bar_units``; none: quarter notes), the bars up to the score's end (:func:`_bars`). A bar
    cut short inside the score (a MIDI time signature set inside a bar) shows as the meter it was played in
    (``2/4`` for half a bar of 4/4)."""
    out: list[tuple[float, str]] = []
    for start, length, unit in _bars(score):
        meter = f"{_number(length / unit)}/{_number(4 / unit)}"
        if not out or out[-1][1] != meter:
            out.append((start, meter))
    return out


def bar_at(score: Score, beat: float) -> str:
    """``bar 3`` (from 1) for a bar's first beat, ``bar 3, beat 2.5`` (beats from 1, in the bar's counted note)
    inside it; bars of 4 quarter notes for a score without bars."""
    starts = np.asarray(score.bar_beats, dtype=float)
    if not len(starts) or beat < starts[0]:
        bar, inside, unit = int(beat // 4), beat % 4, 1.0
    else:
        bar = int(np.searchsorted(starts, beat + 1e-9, side="right")) - 1
        inside = beat - float(starts[bar])
        units = np.asarray(score.bar_units, dtype=float)
        unit = float(units[bar]) if bar < len(units) and units[bar] > 0 else 1.0
    if abs(inside) < 1e-6:
        return f"bar {bar + 1}"
    return f"bar {bar + 1}, beat {_number(inside / unit + 1)}"


def _listed(changes: list[str], total: int) -> str:
    if total <= LISTED_CHANGES:
        return ", ".join(changes)
    return ", ".join(changes[:LISTED_CHANGES]) + f", ... ({total - LISTED_CHANGES} more)"


def tempo_line(score: Score) -> str | None:
    """``tempo: 120 bpm`` and its changes (``; 2 tempo changes: 100 bpm at bar 3, ...``, the first
    :data:`LISTED_CHANGES` listed, then the range of the rest); None for a score with no tempo."""
    changes = tempo_changes(score)
    if not changes:
        return None
    line = f"tempo: {changes[0][1]:.6g} bpm"
    if len(changes) == 1:
        return line + " (no tempo changes)"
    rest = changes[1:]
    low, high = min(b for _, b in changes), max(b for _, b in changes)
    listed = [f"{b:.6g} bpm at {bar_at(score, beat)}" for beat, b in rest[:LISTED_CHANGES]]
    return (f"{line}; tempo changes: {len(rest)} ({low:.6g} to {high:.6g} bpm, read beat by beat): "
            f"{_listed(listed, len(rest))}")


def meter_line(score: Score) -> str | None:
    """``time signature: 4/4`` and its changes (``; time signature changes: 1: 7/8 at bar 5``); None for a score
    without bars."""
    changes = meter_changes(score)
    if not changes:
        return None
    line = f"time signature: {changes[0][1]}"
    if len(changes) == 1:
        return line
    rest = changes[1:]
    listed = [f"{meter} at {bar_at(score, beat)}" for beat, meter in rest[:LISTED_CHANGES]]
    return f"{line}; time signature changes: {len(rest)}: {_listed(listed, len(rest))}"

