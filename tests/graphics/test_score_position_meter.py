"""The view counts a compound meter's beats in eighths while physics plays the score live, not only in the preview.

A music teacher's 12/8 score showed ``beat 1.00`` to ``6.99`` a bar in the live view (quarter notes): physics'
``/batteur/graphics/score_position`` carried no meter, so the view counted every live score in quarter notes. The
message now carries the bar's counted note (``beat_unit``, quarter notes: ``common.score.position.bar_unit``, the
rule ``batteur compare`` and the physics score player's logs count by, ``counted_bar_beat``), and the page shows
``beat / beat_unit + 1``: 1 to 12 in 12/8, 1 to 6 in 6/8. A sender of the four fields before it (a Pd patch) is
still read, counted in quarter notes.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from common.kit import load_kit
from common.messages.graphics import ScorePosition
from common.score.position import counted_bar_beat
from common.score.text import parse_text
from services.graphics.core import GraphicsCore, GraphicsSettings
from services.graphics.preview import score_preview
from services.physics.score_position import score_position

KIT = load_kit()
METERS = {
    # two bars at 90 quarter notes a minute: an eighth is 1/3 s, a 12/8 bar 4 s, a 6/8 bar 2 s
    "12/8": "tempo 90\nmeter 12/8\nHH |x.x.x.x.x.x.x.x.x.x.x.x.|x.x.x.x.x.x.x.x.x.x.x.x.|\n"
            "BD |x.....x.....x.....x.....|x.....x.....x.....x.....|\n",
    "6/8": "tempo 90\nmeter 6/8\nHH |x.x.x.x.x.x.|x.x.x.x.x.x.|\nBD |x.....x.....|x.....x.....|\n",
}
EIGHTHS = {"12/8": 12, "6/8": 6}


def page_count(score: dict[str, float]) -> tuple[int, float]:
    """(bar, beat) as the page says them (services/graphics/web/src/app.js: bar + 1, beat / beat_unit + 1)."""
    return int(score["bar"]) + 1, score["beat"] / score["beat_unit"] + 1


def live_view(meter: str, seconds: float) -> dict[str, float] | None:
    """The view's status ``score`` for physics playing ``meter``'s score from rig time 0 at its written tempo,
    ``seconds`` in, the position sent over the wire (its OSC arguments decoded) as the node sends it."""
    score = parse_text(METERS[meter])
    sent = score_position(score, (0.0, 0.0, 1.0), seconds)
    assert sent is not None
    core = GraphicsCore(GraphicsSettings(latency=0.0, clock="rig"))
    core.handle(ScorePosition.from_args(sent.to_args()), seconds, "physics")
    status = core.status(seconds)["score"]
    assert status is None or isinstance(status, dict)
    return status


@pytest.mark.parametrize("meter", sorted(METERS))
def test_the_live_view_counts_eighths_as_compare_does(meter: str) -> None:
    score = parse_text(METERS[meter])
    eighth = 1 / 3
    shown = []
    for seconds in np.arange(0.05, 2 * EIGHTHS[meter] * eighth, eighth / 2):
        status = live_view(meter, float(seconds))
        assert status is not None and status["beat_unit"] == 0.5, (seconds, status)
        counted = counted_bar_beat(score, float(seconds))  # batteur compare's and the score player's logs' count
        assert counted is not None
        bar, beat = page_count(status)
        # the status gives the beat to 2 decimals of a quarter note: 0.01 eighth
        assert (bar, beat) == (counted[0], pytest.approx(counted[1], abs=0.011)), seconds
        shown.append(beat)
    # every eighth of the bar is counted: 1 to 12 in 12/8 (quarter notes said 1 to 6.99), 1 to 6 in 6/8
    assert min(shown) < 1.2 and EIGHTHS[meter] < max(shown) < EIGHTHS[meter] + 1


def test_the_last_eighth_of_a_twelve_eight_bar_is_beat_twelve() -> None:
    status = live_view("12/8", 4 + 11.5 / 3)  # bar 2, half-way through its twelfth eighth
    assert status is not None and page_count(status) == (2, pytest.approx(12.5, abs=0.01))


def test_a_position_without_the_unit_is_counted_in_quarter_notes() -> None:
    """A sender from before (a Pd patch: time, bar, beat, tempo) is read as it was: quarter notes."""
    old = ScorePosition(time=3.0, bar=1, beat=2.5, tempo_bpm=90.0).to_args()[:5]
    core = GraphicsCore(GraphicsSettings(latency=0.0, clock="rig"))
    core.handle(ScorePosition.from_args(old), 3.0, "pd")
    assert core.status(3.0)["score"] == {"bar": 1, "beat": 2.5, "tempo_bpm": 90.0, "beat_unit": 1.0}


def test_the_preview_of_a_twelve_eight_score_counts_its_eighths(tmp_path: Path) -> None:
    """The preview (the score's own motion, no physics) counts by the same rule as the live view."""
    path = tmp_path / "twelve.txt"
    path.write_text(METERS["12/8"], encoding="utf-8")
    preview = score_preview(path, KIT)
    core = GraphicsCore(GraphicsSettings(latency=0.0), kit=KIT)
    core.load_preview(preview.sequence, preview.impacts, now=10.0, score=preview.score, rate=1.0)
    start = float(preview.sequence.times[0])  # a second before the first note
    shown = 4 + 11.5 / 3  # bar 2, its twelfth eighth
    status = core.status(10.0 + shown - start)["score"]
    counted = counted_bar_beat(preview.score, shown)
    assert status is not None and counted is not None and status["beat_unit"] == 0.5
    assert page_count(status) == (counted[0], pytest.approx(counted[1], abs=0.01))
    assert page_count(status) == (2, pytest.approx(12.5, abs=0.01))
