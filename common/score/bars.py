"""A score's bars in seconds, and a score played with some of its bars repeated (the live drummer's loop).

Bars are counted as :func:`common.score.position.counted_bar_beat` counts them (from 1; a pick-up is bar 0).
A :class:`Timeline` lays pieces of a score (its segments) one after the other: the played score's seconds ("played
time") map piecewise to the written score's, so a loop of bars 3-4 is the score up to the end of bar 4, then bars
3-4 again and again; the physics score player plans the played score as it plans a score, and says positions in the
written one.
"""

from __future__ import annotations

import bisect
import dataclasses
import functools
import math

import numpy as np

from common.score.events import Score
from common.score.position import DEFAULT_BEATS_PER_BAR, last_bar_length, pickup, seconds_at_beat

MAX_LOOP_PASSES = 64
"""A loop lays at most this many passes at once (:func:`loop_passes`) ..."""
MAX_LOOP_NOTES = 2000
"""... and at most this many notes (a bar of 16ths at 400 bpm, x4, asked for 60 s laid 400 passes, 6,400 notes, 3 s
of planning per re-plan) ..."""
MIN_LOOP_COVER = 0.1
"""... but never fewer than cover this share of the time asked (a one-16th bar would otherwise lay 64 passes, a few
tenths of a second: fewer than the time to plan them)."""


def _bar_beats(score: Score, index: int) -> tuple[float, float]:
    """(start, end) of bar ``index`` (from 0, as :func:`common.score.position.bar_beat` numbers them), in beats."""
    bars = np.asarray(score.bar_beats, dtype=float)
    if not len(bars):
        return float(index * DEFAULT_BEATS_PER_BAR), float((index + 1) * DEFAULT_BEATS_PER_BAR)
    if index + 1 < len(bars):
        return float(bars[index]), float(bars[index + 1])
    length = last_bar_length(score)  # bars past the last start are as long as the last one (bar_beat's rule)
    start = float(bars[-1]) + (index - len(bars) + 1) * length
    return start, start + length


def counted_bars(score: Score) -> tuple[int, int]:
    """(first, last) bar numbers of ``score`` as counted (from 1; 0 for a pick-up), the last being the one holding
    its last note."""
    first = 0 if pickup(score) is not None else 1
    if len(score.beats) < 2 or not score.events:
        return first, first - 1
    count = 0
    while seconds_at_beat(score, _bar_beats(score, count + 1)[0]) <= score.events[-1].time + 1e-9:
        count += 1
    return first, first + count


def bar_span(score: Score, bar: int) -> tuple[float, float]:
    """(start, end) score seconds (as written) of counted bar ``bar``; ValueError for a bar the score does not have
    (:func:`counted_bars`)."""
    first, last = counted_bars(score)
    if not first <= bar <= last:
        raise ValueError(f"bar {bar}: the score has bars {first}..{last}")
    start, end = _bar_beats(score, bar - 1 if first == 1 else bar)
    return seconds_at_beat(score, start), seconds_at_beat(score, end)


def bar_end_after(score: Score, seconds: float) -> float:
    """The end (score seconds) of the bar holding score time ``seconds`` (at a bar line: of the bar starting there)."""
    index = 0
    while True:
        _, end = _bar_beats(score, index)
        end_s = seconds_at_beat(score, end)
        if end_s > seconds + 1e-9 or index > 100_000:
            return end_s
        index += 1


@dataclasses.dataclass(frozen=True)
class Segment:
    """A piece of the written score laid in the played one: written ``[start, start + length)`` plays from played
    time ``at``, seconds; ``loop``: a pass of a loop (its bars), else None."""

    at: float
    start: float
    length: float
    loop: tuple[int, int] | None = None

    @property
    def end(self) -> float:
        """Played time it ends, seconds."""
        return self.at + self.length


@dataclasses.dataclass(frozen=True)
class Timeline:
    """The written score ``score`` played as its ``segments`` laid end to end (the last may be endless: the rest of
    the score); :attr:`played` is the score to plan. A long loop's played passes are dropped (:meth:`since`):
    ``earlier`` counts them, per loop (its bars), so the pass numbers go on."""

    score: Score
    segments: tuple[Segment, ...]
    earlier: tuple[tuple[tuple[int, int], int], ...] = ()
    """(bars, passes) of the loops' passes dropped before the first segment (:meth:`since`)."""

    @classmethod
    def plain(cls, score: Score) -> Timeline:
        """The score as written."""
        return cls(score, (Segment(0.0, 0.0, math.inf),))

    def index(self, played: float) -> int:
        """The segment holding played time ``played`` (s); before the first: the first (a time before the segments
        kept, :meth:`since`, is said as if in it), past the last: the last."""
        # the first whose end is after ``played`` (the segments lie end to end: their ends ascend); a bisection, as
        # the live player asks at every step and a long loop keeps thousands of passes
        k = bisect.bisect_right(self.segments, played, key=lambda seg: seg.end - 1e-9)
        return min(k, len(self.segments) - 1)

    def written(self, played: float) -> float:
        """Written score seconds at played time ``played`` (s)."""
        seg = self.segments[self.index(played)]
        return seg.start + (played - seg.at)

    @functools.cached_property
    def last_pass(self) -> int | None:
        """Index of the last pass of a loop in :attr:`segments`, None with none (found once: the live player asks
        at every step)."""
        return next((k for k in range(len(self.segments) - 1, -1, -1) if self.segments[k].loop is not None), None)

    @property
    def looping(self) -> bool:
        return self.last_pass is not None

    @property
    def loop_end(self) -> float:
        """Played time (s) the last pass of the loop ends (-inf with none)."""
        return -math.inf if self.last_pass is None else self.segments[self.last_pass].end

    @functools.cached_property
    def pass_numbers(self) -> tuple[int, ...]:
        """Per segment, how many of the segments up to it (it too) are passes of its loop (its bars; 0 for no
        loop): the pass number the log says at a wrap."""
        seen: dict[tuple[int, int], int] = dict(self.earlier)
        numbers = []
        for seg in self.segments:
            if seg.loop is not None:
                seen[seg.loop] = seen.get(seg.loop, 0) + 1
            numbers.append(0 if seg.loop is None else seen[seg.loop])
        return tuple(numbers)

    def passes(self, played: float = math.inf) -> dict[tuple[int, int], int]:
        """Per loop (its bars), how many of its passes start before played time ``played`` (s) (those dropped too):
        the passes a play that ended there reached."""
        counts = dict(self.earlier)
        for seg in self.segments:
            if seg.at >= played - 1e-9:
                break
            if seg.loop is not None:
                counts[seg.loop] = counts.get(seg.loop, 0) + 1
        return counts

    def since(self, played: float) -> Timeline:
        """This timeline without the segments that ended before the one holding played time ``played`` (s) but the
        last of them (the segment before the one in progress is where a wrap is said from): a long loop's played
        passes, which every re-plan would lay out again (its plan and the pass numbers to look through grew with
        each pass). The passes dropped stay counted (:attr:`earlier`). Played times from the segment before the one
        holding ``played`` on are said as before."""
        k = self.index(played) - 1
        if k <= 0:
            return self
        counts = dict(self.earlier)
        for seg in self.segments[:k]:
            if seg.loop is not None:
                counts[seg.loop] = counts.get(seg.loop, 0) + 1
        return Timeline(self.score, self.segments[k:], tuple(counts.items()))

    def cut(self, played: float) -> tuple[Segment, ...]:
        """The segments up to played time ``played`` (s), the one holding it shortened to end there."""
        out: list[Segment] = []
        for seg in self.segments:
            if seg.at >= played - 1e-9:
                break
            out.append(dataclasses.replace(seg, length=min(seg.length, played - seg.at)))
        return tuple(out)

    def continuation(self, played: float) -> tuple[Segment, ...]:
        """The segments from the start up to the end of the one holding played time ``played`` (s), then the rest
        of the written score from where that one ends (what plays when no more loop passes follow)."""
        k = self.index(played)
        seg = self.segments[k]
        kept = self.segments[:k + 1]
        if math.isinf(seg.length):
            return kept
        return (*kept, Segment(seg.end, seg.start + seg.length, math.inf))

    @property
    def played(self) -> Score:
        """The score to plan: each segment's notes and beats (written times in ``[start, start + length)``, the
        last segment's to the end) moved to its played times."""
        score = self.score
        beats = np.asarray(score.beats, dtype=float)
        events, played_beats = [], []
        for seg in self.segments:
            shift = seg.at - seg.start
            stop = seg.start + seg.length - 1e-9
            events += [dataclasses.replace(e, time=e.time + shift) for e in score.events
                       if seg.start - 1e-9 <= e.time < stop]
            played_beats.append(beats[(beats >= seg.start - 1e-9) & (beats < stop)] + shift)
        return dataclasses.replace(score, events=events, beats=np.concatenate(played_beats) if played_beats else beats)


def looped(timeline: Timeline, played: float, bars: tuple[int, int] | None, cover_s: float) -> Timeline:
    """``timeline`` from played time ``played`` (s) on with ``bars`` (counted, first and last) looped, or looping
    off (None). The loop takes over where the play, going on from ``played`` (after a pass of a loop in
    progress: with the rest of the score), next reaches the end of bar ``last``; if it never does (the play is past
    it), at the end of the pass in progress, else of the bar in progress; from there bars ``first``..``last``
    repeat for ``cover_s`` score seconds (as many passes as :func:`loop_passes` lays). Off: the pass in progress
    ends, then the rest of the score."""
    path = timeline.continuation(played)
    if bars is None:
        return Timeline(timeline.score, path, timeline.earlier)
    score = timeline.score
    start, _ = bar_span(score, bars[0])
    _, end = bar_span(score, bars[1])
    junction = None
    for seg in path:
        if seg.start < end + 1e-9 <= seg.start + seg.length + 2e-9 and seg.at + (end - seg.start) >= played - 1e-9:
            junction = seg.at + (end - seg.start)
            break
    if junction is None:
        held = path[timeline.index(played)]
        if math.isfinite(held.length) and held.end >= played:
            junction = held.end
        else:
            junction = held.at + bar_end_after(score, held.start + (played - held.at)) - held.start
    length = end - start
    passes = loop_passes(score, bars, cover_s)
    laid = Timeline(score, path).cut(junction)
    loop = tuple(Segment(junction + k * length, start, length, bars) for k in range(passes))
    return Timeline(score, (*laid, *loop), timeline.earlier)


def loop_passes(score: Score, bars: tuple[int, int], cover_s: float) -> int:
    """How many passes of counted bars ``bars`` (first, last) :func:`looped` lays to cover ``cover_s`` score seconds:
    enough for them, two at least, but at most :data:`MAX_LOOP_PASSES` and :data:`MAX_LOOP_NOTES` notes, unless
    that covers less than :data:`MIN_LOOP_COVER` of ``cover_s``."""
    start, _ = bar_span(score, bars[0])
    _, end = bar_span(score, bars[1])
    length = end - start
    notes = loop_notes(score, bars)
    cap = max(min(MAX_LOOP_PASSES, MAX_LOOP_NOTES // max(notes, 1)), math.ceil(MIN_LOOP_COVER * cover_s / length))
    return max(2, min(math.ceil(cover_s / length), cap))


def loop_notes(score: Score, bars: tuple[int, int]) -> int:
    """How many notes a pass of counted bars ``bars`` (first, last) plays (a segment's, as :attr:`Timeline.played`
    takes them)."""
    start, _ = bar_span(score, bars[0])
    _, end = bar_span(score, bars[1])
    return sum(1 for e in score.events if start - 1e-9 <= e.time < end - 1e-9)
