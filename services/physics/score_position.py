"""Where the playing score is, for the view's status panel (``/batteur/graphics/score_position``).

The live node sends one every :data:`SCORE_POSITION_PERIOD_S` while a score plays; the view drops a position
older than a second, so a stopped or paused score leaves the panel empty.
"""

from __future__ import annotations

from common.messages.graphics import ScorePosition
from common.score.events import Score
from common.score.position import bar_beat, bar_unit

SCORE_POSITION_PERIOD_S = 0.1
"""Seconds between two positions sent (the panel shows beats to two decimals; ten a second read smoothly)."""

_MAX_BEAT = 64.0  # ScorePosition's bounds: a bar of more beats, or a tempo past 1,000 bpm, is shown at the bound
_MAX_BPM = 1000.0
_MAX_UNIT = 4.0  # a whole note (x/1); a unit the view cannot be sent is counted in quarter notes


def score_position(score: Score, mapping: tuple[float, float, float], now: float) -> ScorePosition | None:
    """The position of ``score`` at rig time ``now`` (s) under ``mapping`` = (rig time s, score position s as
    written, tempo factor) of one instant (:attr:`ScorePlayer.mapping`); None before the score's first beat or
    for a score without beats. The tempo is the written tempo times the factor. The bar's counted note
    (``beat_unit``: eighths in 12/8) is :func:`~common.score.position.bar_unit`'s, as ``batteur compare`` and the
    view's preview count; until 7 Dec none was sent and the view counted a 12/8 bar's quarter notes, 1 to 6."""
    at, position, tempo = mapping
    where = bar_beat(score, position + (now - at) * tempo)
    if where is None:
        return None
    unit = bar_unit(score, where.bar)
    return ScorePosition(time=now, bar=where.bar, beat=min(where.beat, _MAX_BEAT),
                         tempo_bpm=min(where.tempo_bpm * tempo, _MAX_BPM),
                         beat_unit=unit if 0 < unit <= _MAX_UNIT else 1.0)
