"""The preview's status counts a compound meter's beats as a DAW and ``batteur compare`` do: in 6/8 the eighths,
1 to 6 (the page counted quarter notes, 1 to 3.99, whatever the meter). The node's status carries the bar's counted
beat (``beat_unit``, quarter notes: ``Score.bar_units``); the beat stays in quarter notes, as physics' score
player sends it."""

from __future__ import annotations

from pathlib import Path

import pytest

from common.kit import load_kit
from common.score.position import bar_beat
from services.graphics.core import GraphicsCore, GraphicsSettings
from services.graphics.preview import score_preview
from tests.graphics.conftest import GraphicsNodeProcess, needs_browser, open_page

pytestmark = pytest.mark.timeout(120)

KIT = load_kit()
SIX_EIGHT = """# two bars of 6/8 at 90 quarter notes a minute: an eighth is 1/3 s, a bar 2 s
tempo 90
meter 6/8
HH |x.x.x.x.x.x.|x.x.x.x.x.x.|
SN |......x.....|......x.....|
BD |x...........|x.....x.....|
"""


@pytest.fixture
def score(tmp_path: Path) -> Path:
    path = tmp_path / "six.txt"
    path.write_text(SIX_EIGHT, encoding="utf-8")
    return path


def test_the_status_gives_the_preview_s_beat_unit(score: Path) -> None:
    preview = score_preview(score, KIT)
    core = GraphicsCore(GraphicsSettings(latency=0.0), kit=KIT)
    core.load_preview(preview.sequence, preview.impacts, now=10.0, score=preview.score, rate=1.0)
    start = preview.sequence.times[0]  # a second before the first note
    # bar 2's sixth eighth (5/3 s into it): 2.5 quarter notes from 0, counted in eighths (0.5 quarter notes)
    shown = 2.0 + 5 / 3
    where = bar_beat(preview.score, shown)
    assert where is not None and (where.bar, where.beat) == (1, pytest.approx(2.5))
    assert core.status(10.0 + shown - start)["score"] == {"bar": 1, "beat": 2.5, "tempo_bpm": 90.0, "beat_unit": 0.5}


STATUS = "() => document.getElementById('status-body').innerText"


@needs_browser
def test_the_page_counts_six_eight_in_eighths(score: Path, tmp_path: Path) -> None:
    """Once the preview is past a bar's fourth eighth (2 quarter notes in), the page says its beat in eighths: the
    status's beat over its unit, from 1 (``beat 5.xx``; quarter notes said ``beat 3.xx``)."""
    node = GraphicsNodeProcess(tmp_path, latency=0.0, extra=[
        "--no-oscquery", "--preview-score", str(score), "--clock-master", "self"])
    node.start()
    try:
        with open_page(node.url, 5, 1000, 600, wait_for_status=True) as (page, errors):
            # the status and its text together (a status is shown as it arrives), once past the fourth eighth
            status, text = page.wait_for_function(
                f"() => {{ const s = window.batteur.status && window.batteur.status.score;"
                f" return s && s.beat >= 2 ? [s, ({STATUS})()] : null; }}", timeout=30000).json_value()
            assert status["beat_unit"] == 0.5, status
            beat = status["beat"] / 0.5 + 1  # 5 to 6.99: the fifth and sixth eighths
            assert 5 <= beat < 7 and f"bar {status['bar'] + 1} beat {beat:.2f} @ 90 bpm" in text, (status, text)
            assert errors == []
    finally:
        node.close()
