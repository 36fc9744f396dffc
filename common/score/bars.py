"""A score's bars in seconds, and a score played with some of its bars repeated (the live drummer's loop).

Bars are counted as :func:`common.score.position.counted_bar_beat` counts them (from 1; a pick-up is bar 0).
A :class:`Timeline` lays pieces of a score (its segments) one after the other: the played score's seconds ("played
time") map piecewise to the written score's, so a loop of bars 3-4 is the score up to the end of bar 4, then bars
3-4 again and again; the physics score player plans the played score as it plans a score, and says positions in the
written one.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from common.score.events import Score
from common.score.position import DEFAULT_BEATS_PER_BAR, pickup


def _beat_time(score: Score, beat: float) -> float:
    """Score seconds at ``beat`` (beats from the first, fractional); past the last beat its spacing goes on."""
    beats = np.asarray(score.beats, dtype=float)
    last = len(beats) - 1
    if beat <= last:
        return float(np.interp(beat, np.arange(len(beats)), beats))
    return float(beats[-1] + (beat - last) * (beats[-1] - beats[-2]))


def _bar_beats(score: Score, index: int) -> tuple[float, float]:
    """(start, end) of bar ``index`` (from 0, as :func:`common.score.position.bar_beat` numbers them), in beats."""
    bars = np.asarray(score.bar_beats, dtype=float)
    if not len(bars):
        return float(index * DEFAULT_BEATS_PER_BAR), float((index + 1) * DEFAULT_BEATS_PER_BAR)
    if index + 1 < len(bars):
        return float(bars[index]), float(bars[index + 1])
    # bars past the last start are as long as the last one (bar_beat's rule)
    length = len(score.beats) - 1 - float(bars[-1])
    if length <= 0:
        length = float(bars[-1] - bars[-2]) if len(bars) > 1 else float(DEFAULT_BEATS_PER_BAR)
    start = float(bars[-1]) + (index - len(bars) + 1) * length
    return start, start + length


def counted_bars(score: Score) -> tuple[int, int]:
    """(first, last) bar numbers of ``score`` as counted (from 1; 0 for a pick-up), the last being the one holding
    its last note."""
    first = 0 if pickup(score) is not None else 1
    if len(score.beats) < 2 or not score.events:
        return first, first - 1
    count = 0
    while _beat_time(score, _bar_beats(score, count + 1)[0]) <= score.events[-1].time + 1e-9:
        count += 1
    return first, first + count


def bar_span(score: Score, bar: int) -> tuple[float, float]:
    """(start, end) score seconds (as written) of counted bar ``bar``; ValueError for a bar the score does not have
    (:func:`counted_bars`)."""
    first, last = counted_bars(score)
    if not first <= bar <= last:
        raise ValueError(f"bar {bar}: the score has bars {first}..{last}")
    start, end = _bar_beats(score, bar - 1 if first == 1 else bar)
    return _beat_time(score, start), _beat_time(score, end)


def bar_end_after(score: Score, seconds: float) -> float:
    """The end (score seconds) of the bar holding score time ``seconds`` (at a bar line: of the bar starting there)."""
    index = 0
    while True:
        _, end = _bar_beats(score, index)
        end_s = _beat_time(score, end)
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
    the score); :attr:`played` is the score to plan."""

    score: Score
    segments: tuple[Segment, ...]

    @classmethod
    def plain(cls, score: Score) -> Timeline:
        """The score as written."""
        return cls(score, (Segment(0.0, 0.0, math.inf),))

    def index(self, played: float) -> int:
        """The segment holding played time ``played`` (s); before the first: the first, past the last: the last."""
        for k, seg in enumerate(self.segments):
            if played < seg.end - 1e-9:
                return k
        return len(self.segments) - 1

    def written(self, played: float) -> float:
        """Written score seconds at played time ``played`` (s)."""
        seg = self.segments[self.index(played)]
        return seg.start + (played - seg.at)

    @property
    def looping(self) -> bool:
        return any(seg.loop is not None for seg in self.segments)

    @property
    def loop_end(self) -> float:
        """Played time (s) the last pass of the loop ends (-inf with none)."""
        return max((seg.end for seg in self.segments if seg.loop is not None), default=-math.inf)

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
    repeat for at least ``cover_s`` score seconds (two passes at least). Off: the pass in progress ends, then the
    rest of the score."""
    path = timeline.continuation(played)
    if bars is None:
        return Timeline(timeline.score, path)
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
    passes = max(2, math.ceil(cover_s / length))
    laid = Timeline(score, path).cut(junction)
    loop = tuple(Segment(junction + k * length, start, length, bars) for k in range(passes))
    return Timeline(score, (*laid, *loop))
