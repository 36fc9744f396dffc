"""A score's length, tempo and time signatures as a DAW shows them: ``python -m common.score``'s header and the
score length ``batteur render`` reports.

Worked out from what every reader fills in (:class:`common.score.events.Score`): ``beats`` (each quarter note's
time), ``bar_beats`` and ``bar_units`` (where the bars start, the note each is counted in) and ``end_beat``. The
tempo is read beat by beat: a change inside a beat shows as that beat's average, then the new tempo from the next.
"""

from __future__ import annotations

import numpy as np

from common.score.events import Score
from common.score.position import pickup, seconds_at_beat

LISTED_CHANGES = 6
"""The most tempo or time signature changes the header lists one by one (more: counted, with their range)."""
BPM_DECIMALS = 2
"""Tempos are read and said to a hundredth of a bpm: a MIDI file holds a tempo as whole microseconds a beat, so 96.25
bpm is 623,377 us, 96.2499 bpm (said so until 8 Dec); a microsecond is 0.0003 bpm at 140 bpm, far below a hundredth,
and two beats' tempos that round alike are one tempo (the readers' rounding)."""
MIN_RAMP_STEPS = 3
"""Tempo changes on this many beats in a row, each the same way and of a like size (:data:`RAMP_STEP_RATIO`), are one
ramp, an accelerando or a ritardando, said as one change (until 8 Dec an accelerando's per-beat changes filled the
list, and a sudden change after it was cut off as "... (12 more)")."""
RAMP_STEP_RATIO = 3.0
"""A step more than this many times the one before it (or less than its inverse) is not the ramp's: a jump."""


def score_length(score: Score) -> tuple[float, int] | None:
    """(beats, bars) of ``score`` up to its end (:attr:`Score.end_beat`: a text score's last bar, a MIDI file's end
    of track): beats in quarter notes to a hundredth from its first bar line (a part of a score starting inside a
    beat, ``batteur render --bars 2`` of a 7/8 file, counts from there: 4.0 beats for 3.5 until 8 Dec), the bars
    starting before the end; None when its reader does not know its end (a live or performed score)."""
    if score.end_beat is None:
        return None
    starts = np.asarray(score.bar_beats, dtype=float)
    first = float(starts[0]) if len(starts) and starts[0] > 0 else 0.0
    return round(score.end_beat - first, 2), int(np.count_nonzero(starts < score.end_beat - 1e-9))


def _bars(score: Score) -> list[tuple[float, float, float]]:
    """(start, length, counted note) of each bar up to the score's end, beats: a bar's length runs to the next start
    (the last one to the score's end when no start follows). A last bar ending where the score does, shorter than
    the one before it in the same counted note, and followed by a start a bar as long as that one, is one the end
    cuts short (a text score closing on a half-bar rest): it keeps that bar's length, as a DAW's bar ruler does."""
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
    # the bar after the end as long as the one before the last: the last is cut short (a text score's closing rest
    # puts a start at its end and a whole bar after it); none after, or one as short: a bar of its own meter (a
    # MIDI file's 6/8 after 7/8, now that its end is on a bar line; a text score's last `meter 2/4` bar, which read
    # as 4/4 until 8 Dec)
    after = float(starts[counted + 1] - starts[counted]) if counted + 1 < len(starts) else None
    if (len(bars) >= 2 and score.end_beat is not None and abs(sum(bars[-1][:2]) - score.end_beat) < 1e-9
            and bars[-1][2] == bars[-2][2] and bars[-1][1] < bars[-2][1] - 1e-9
            and after is not None and abs(after - bars[-2][1]) < 1e-9):
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
    bpm = np.round(60.0 / np.diff(beats), BPM_DECIMALS)
    changed = np.flatnonzero(np.diff(bpm) != 0) + 1
    return [(0.0, float(bpm[0]))] + [(float(k), float(bpm[k])) for k in changed]


def bpm_words(bpm: float) -> str:
    """A tempo to a hundredth of a bpm, without trailing zeros: ``96.25``, ``120``, ``93.13``."""
    return f"{bpm:.{BPM_DECIMALS}f}".rstrip("0").rstrip(".")


def _ramp_end(changes: list[tuple[float, float]], first: int) -> int:
    """The last of the changes from ``changes[first]`` on that continue it as a ramp: each on the beat after the one
    before, the same way, its step within :data:`RAMP_STEP_RATIO` of the one before."""
    last = first
    step = changes[first][1] - changes[first - 1][1]
    while last + 1 < len(changes):
        beat, bpm = changes[last + 1]
        next_step = bpm - changes[last][1]
        if (abs(beat - changes[last][0] - 1) > 1e-9 or next_step * step <= 0
                or not 1 / RAMP_STEP_RATIO <= abs(next_step / step) <= RAMP_STEP_RATIO):
            break
        last, step = last + 1, next_step
    return last


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
    inside it, counted as :func:`common.score.position.counted_bar_beat` counts (after a pick-up the first full bar
    is bar 1, the pick-up bar 0: until 8 Dec a change was said a bar too late there); bars of 4 quarter notes for a
    score without bars."""
    starts = np.asarray(score.bar_beats, dtype=float)
    if not len(starts) or beat < starts[0]:
        bar, inside, unit = int(beat // 4), beat % 4, 1.0
        return f"bar {bar + 1}" if abs(inside) < 1e-6 else f"bar {bar + 1}, beat {_number(inside / unit + 1)}"
    bar = int(np.searchsorted(starts, beat + 1e-9, side="right")) - 1
    inside = beat - float(starts[bar])
    units = np.asarray(score.bar_units, dtype=float)
    unit = float(units[bar]) if bar < len(units) and units[bar] > 0 else 1.0
    short = pickup(score)
    number = bar if short is not None else bar + 1
    if short is not None and bar == 0:  # a pick-up's beats are the end of a full bar
        inside += short[1] - short[0]
        unit = float(units[1]) if len(units) > 1 and units[1] > 0 else 1.0
    if abs(inside) < 1e-6:
        return f"bar {number}"
    return f"bar {number}, beat {_number(inside / unit + 1)}"


def _listed(changes: list[str], total: int) -> str:
    if total <= LISTED_CHANGES:
        return ", ".join(changes)
    return ", ".join(changes[:LISTED_CHANGES]) + f", ... ({total - LISTED_CHANGES} more)"


def tempo_items(score: Score, changes: list[tuple[float, float]]) -> list[str]:
    """The changes after the first of ``changes`` (:func:`tempo_changes`) as a musician says them: a jump as ``90
    bpm at bar 11``, a ramp (:data:`MIN_RAMP_STEPS`) as ``accelerando 90 -> 140 bpm (16 steps, bar 5 to bar 8, beat
    4)``."""
    items = []
    k = 1
    while k < len(changes):
        last = _ramp_end(changes, k)
        if last - k + 1 >= MIN_RAMP_STEPS:
            before, after = changes[k - 1][1], changes[last][1]
            kind = "accelerando" if after > before else "ritardando"
            items.append(f"{kind} {bpm_words(before)} -> {bpm_words(after)} bpm ({last - k + 1} steps, "
                         f"{bar_at(score, changes[k][0])} to {bar_at(score, changes[last][0])})")
            k = last + 1
        else:
            items.append(f"{bpm_words(changes[k][1])} bpm at {bar_at(score, changes[k][0])}")
            k += 1
    return items


def tempo_line(score: Score) -> str | None:
    """``tempo: 120 bpm`` and its changes (``; tempo changes: 2 (90 to 140 bpm, read beat by beat): 90 bpm at bar
    3, accelerando 90 -> 140 bpm (8 steps, bar 5 to bar 6, beat 4)``: :func:`tempo_items`, the first
    :data:`LISTED_CHANGES` listed, then how many more); None for a score with no tempo."""
    changes = tempo_changes(score)
    if not changes:
        return None
    line = f"tempo: {bpm_words(changes[0][1])} bpm"
    if len(changes) == 1:
        return line + " (no tempo changes)"
    items = tempo_items(score, changes)
    low, high = min(b for _, b in changes), max(b for _, b in changes)
    return (f"{line}; tempo changes: {len(items)} ({bpm_words(low)} to {bpm_words(high)} bpm, read beat by beat): "
            f"{_listed(items[:LISTED_CHANGES], len(items))}")


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

