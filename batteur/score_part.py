"""``batteur render --bars A-B``: a part of a score, its bars counted as ``python -m common.score`` prints them.

The part is a score of its own on the score's clock shifted to start at bar A's start (its score time 0): its notes,
beats and bar lines from there to the end of bar B, so the render plans and simulates only them (the usual settle
and lead-in before the first note). report.json's ``bars`` says which part and where it starts in the whole score.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from batteur.errors import UsageError
from common.score.bars import _bar_beats, counted_bars
from common.score.events import Score
from common.score.position import seconds_at_beat
from common.score.summary import score_length

EARLY_S = 0.05
"""A note up to this long (seconds) before a bar line is the bar's, not the one before: a flam's grace note, a drummer
playing ahead of the beat (Groove's performances are up to tens of milliseconds early); a part's first note may then
lie that much before its score time 0. At a bar line the window is at most :data:`EARLY_NOTE_BEATS` at the local
tempo: until 8 Dec a 32nd note at 180 bpm (42 ms) before a bar line moved to the next bar's part."""
EARLY_NOTE_BEATS = 1 / 16
"""A 64th note (quarter notes): the longest a note may lie before a bar line and be that bar's, shorter than any
written note before it (a 32nd's 1/8 beat) at any tempo."""
SCORE_ATTRIBUTES = ("grip", "nuance", "kit", "kit_line")
"""A text score's directives: attributes, not fields (kept by the part, as :func:`batteur.render.scale_tempo` keeps
them)."""


def parse_bars(text: str) -> tuple[int, int]:
    """``--bars``: ``"5-8"`` (bars 5 to 8) or ``"5"`` (bar 5 alone) as (first, last); :class:`UsageError` (exit 2)
    for another form, a negative bar or a range ending before it starts."""
    first, sep, last = text.strip().partition("-")
    try:
        bars = (int(first), int(last) if sep else int(first))
    except ValueError:
        raise UsageError(f"--bars {text!r}: a bar or a range of bars as `python -m common.score SCORE` counts them "
                         "(from 1; a pick-up is bar 0), e.g. 5 or 5-8") from None
    if bars[1] < bars[0]:
        raise UsageError(f"--bars {text}: the range ends (bar {bars[1]}) before it starts (bar {bars[0]}): give "
                         f"{bars[1]}-{bars[0]}")
    return bars


def _beat_position(beats: np.ndarray, seconds: float) -> float:
    """Where score time ``seconds`` falls in ``beats`` (a fractional index; past the ends the nearest spacing goes
    on)."""
    if seconds <= beats[0]:
        return float((seconds - beats[0]) / (beats[1] - beats[0]))
    if seconds >= beats[-1]:
        return float(len(beats) - 1 + (seconds - beats[-1]) / (beats[-1] - beats[-2]))
    return float(np.interp(seconds, beats, np.arange(len(beats))))


def _bar_seconds(score: Score, bar: int, low: int) -> tuple[float, float]:
    """(start, end) score seconds of counted bar ``bar`` (the first counted ``low``: 0 with a pick-up), as
    :func:`common.score.bars.bar_span` finds them, past the bar of the last note too (empty bars to the score's end)."""
    start, end = _bar_beats(score, bar - 1 if low == 1 else bar)
    return seconds_at_beat(score, start), seconds_at_beat(score, end)


def _part_bar_lines(score: Score, start_pos: float, end_pos: float) -> tuple[np.ndarray, np.ndarray]:
    """The bar lines (beats, as :attr:`Score.bar_beats`, not yet moved) and their counted notes of the part from beat
    ``start_pos`` to ``end_pos``, the first at ``start_pos`` (past the score's last bar start the bars are as long as
    the last: their lines are not in ``bar_beats``, and the part starts with one); none for a score without."""
    bar_beats = np.asarray(score.bar_beats, dtype=float)
    units = np.asarray(score.bar_units, dtype=float)
    if not len(bar_beats):
        return bar_beats, units
    if len(units) != len(bar_beats):  # quarter notes
        units = np.ones(len(bar_beats))
    inside = (bar_beats >= start_pos - 1e-9) & (bar_beats < end_pos - 1e-9)
    lines, counted = bar_beats[inside], units[inside]
    if not len(lines) or lines[0] > start_pos + 1e-9:
        before = max(int(np.searchsorted(bar_beats, start_pos + 1e-9, side="right")) - 1, 0)
        lines, counted = np.concatenate([[start_pos], lines]), np.concatenate([[units[before]], counted])
    return lines, counted


def _early_s(score: Score, position: float) -> float:
    """How long (seconds) before the bar line at beat ``position`` a note is still that bar's: :data:`EARLY_S`, at
    most :data:`EARLY_NOTE_BEATS` at the tempo just before the line (at the score's start: just after it)."""
    line = seconds_at_beat(score, position)
    if position < EARLY_NOTE_BEATS:
        return min(EARLY_S, seconds_at_beat(score, position + EARLY_NOTE_BEATS) - line)
    return min(EARLY_S, line - seconds_at_beat(score, position - EARLY_NOTE_BEATS))


def bar_part(score: Score, bars: tuple[int, int], name: str) -> tuple[Score, float, float]:
    """The part of ``score`` (its file's ``name`` in an error) from the start of bar ``bars[0]`` to the end of bar
    ``bars[1]`` (counted as :func:`common.score.bars.counted_bars` counts them), and where it lies in the whole score
    (start, end score seconds). The part's score time 0 is the first bar's start; it holds the notes from
    :func:`_early_s` before it to :func:`_early_s` before the last bar's end (to the end itself for the score's last
    bar), its beats and its bar lines.
    :class:`UsageError` (exit 2) for bars the score does not have."""
    low, high = counted_bars(score)  # to the bar of the last note ...
    length = score_length(score)
    if length is not None:  # ... or to the score's end, as `python -m common.score` counts them (empty bars there)
        high = max(high, low + length[1] - 1)
    first, last = bars
    given = f"{first}" if first == last else f"{first}-{last}"  # as one bar is given: not "--bars 5-5"
    if len(score.beats) < 2 or high < low:
        raise UsageError(f"--bars {given}: {name} has no bars to count (no beats or no notes)")
    if not low <= first <= last <= high:
        raise UsageError(f"--bars {given}: {name} has bars {low} to {high} (`python -m common.score {name}` "
                         "lists them)")
    start, end = _bar_seconds(score, first, low)[0], _bar_seconds(score, last, low)[1]
    beats = np.asarray(score.beats, dtype=float)
    origin = int(np.searchsorted(beats, start + 1e-9, side="right")) - 1  # the beat at (or before) the start
    origin = max(origin, 0)
    start_pos, end_pos = _beat_position(beats, start), _beat_position(beats, end)
    kept_beats = beats[origin:][beats[origin:] <= end + 1e-9]
    bar_beats, units = _part_bar_lines(score, start_pos, end_pos)

    early_start, early_end = _early_s(score, start_pos), _early_s(score, end_pos)
    to_the_end = last == high  # the score's last bar: its notes are nobody else's, keep them all (until 8 Dec its
    # last note, inside EARLY_S of the end, was left out)

    def inside(time: float) -> bool:
        if time < start - early_start:
            return False
        return time <= end + 1e-9 if to_the_end else time < end - early_end

    part = dataclasses.replace(
        score,
        events=[dataclasses.replace(e, time=e.time - start) for e in score.events if inside(e.time)],
        beats=kept_beats - start,
        unknown=[dataclasses.replace(u, time=u.time - start) for u in score.unknown if inside(u.time)],
        duplicates=[dataclasses.replace(d, time=d.time - start) for d in score.duplicates if inside(d.time)],
        bar_beats=bar_beats - origin,
        bar_units=units,
        end_beat=end_pos - origin,
    )
    for attribute in SCORE_ATTRIBUTES:
        if hasattr(score, attribute):
            setattr(part, attribute, getattr(score, attribute))
    return part, start, end


def part_json(bars: tuple[int, int], start_s: float, end_s: float) -> dict[str, Any]:
    """report.json's ``bars``: the bars rendered and where they lie in the whole score (score seconds, at
    ``--tempo-scale``); the render's score time 0 is ``start_s`` of the whole score."""
    return {"first": bars[0], "last": bars[1], "start_s": round(start_s, 6), "end_s": round(end_s, 6)}
