"""Where the playing score is, for the view's status panel (``/batteur/graphics/score_position``).

The live node sends one every :data:`SCORE_POSITION_PERIOD_S` while a score plays; the view drops a position
older than a second, so a stopped or paused score leaves the panel empty.
"""

from __future__ import annotations

from common.messages.graphics import ScorePosition
from common.score.events import Score
from common.score.position import bar_beat

SCORE_POSITION_PERIOD_S = 0.1
"""Seconds between two positions sent (the panel shows beats to two decimals; ten a second read smoothly)."""

_MAX_BEAT = 64.0  # ScorePosition's bounds: a bar of more beats, or a tempo past 1,000 bpm, is shown at the bound
_MAX_BPM = 1000.0


def score_position(score: Score, mapping: tuple[float, float, float], now: float) -> ScorePosition | None:
    """The position of ``score`` at rig time ``now`` (s) under ``mapping`` = (rig time s, score position s as
    written, tempo factor) of one instant (:attr:`ScorePlayer.mapping`); None before the score's first beat or
    for a score without beats. The tempo is the written tempo times the factor."""
    at, position, tempo = mapping
    where = bar_beat(score, position + (now - at) * tempo)
    if where is None:
        return None
    return ScorePosition(time=now, bar=where.bar, beat=min(where.beat, _MAX_BEAT),
                         tempo_bpm=min(where.tempo_bpm * tempo, _MAX_BPM))
