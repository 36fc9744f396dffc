"""The score preview's position and speed (``batteur graphics --preview-score SCORE [--preview-rate R]``).

A teacher's walkthrough: while the preview played, the status panel showed ``score –`` and ``poses 0 · impacts 0``
(the score position came only from physics' score player, the counts only from poses and impacts received), and
nothing slowed the preview down. The status now shows the preview's bar and beat (``common.score.position.bar_beat``
of the motion shown, as physics' score player computes them) and its own counts; ``--preview-rate`` and the page's
*speed* select play the planned motion slower or faster, from where it is.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from common.kit import load_kit
from common.messages.graphics import GraphicsMode
from common.score.position import bar_beat
from services.graphics.core import GraphicsCore, GraphicsSettings
from services.graphics.node import GraphicsNodeSettings, make_core
from services.graphics.preview import LOOP_PAUSE_S, PreviewClock, bar_span, parse_bars, score_preview
from services.graphics.server import ViewServer
from tests.graphics.conftest import ROOT, GraphicsNodeProcess, needs_browser, open_page

KIT = load_kit()
BAR = """# two bars of rock at 120 bpm: a beat is 0.5 s
tempo 120
meter 4/4
HH |xxxxxxxx|xxxxxxxx|
SN |..X...X.|..X...X.|
BD |x...x...|x...x...|
"""


@pytest.fixture
def bars(tmp_path: Path) -> Path:
    path = tmp_path / "bars.txt"
    path.write_text(BAR, encoding="utf-8")
    return path


def test_the_clock_at_half_rate_plays_half_a_second_of_motion_per_second() -> None:
    clock = PreviewClock(start=-1.0, span=5.0, now=100.0, rate=0.5)
    for wall, shown in ((100.0, -1.0), (101.0, -0.5), (102.0, 0.0), (108.0, 3.0), (110.0, 4.0)):
        assert clock.position(wall) == pytest.approx(shown), wall
    # one lap is the motion and the pause after it, both at the rate: 5.5 motion seconds, 11 wall seconds
    assert clock.lap(110.9) == 0 and clock.lap(111.0) == 1
    assert clock.position(111.0 + 2.0) == pytest.approx(-1.0 + 1.0)
    assert LOOP_PAUSE_S == 0.5


def test_a_rate_changed_while_playing_goes_on_from_where_the_motion_is() -> None:
    clock = PreviewClock(start=0.0, span=10.0, now=0.0, rate=1.0)
    assert clock.position(2.0) == pytest.approx(2.0)
    clock.set_rate(0.5, now=2.0)
    assert clock.position(2.0) == pytest.approx(2.0)  # no jump
    assert clock.position(4.0) == pytest.approx(3.0)
    clock.set_rate(2.0, now=4.0)
    assert clock.position(5.0) == pytest.approx(5.0)
    clock.shift(3.0)  # the rig clock stepped 3 s forward: the motion shown stays
    assert clock.position(8.0) == pytest.approx(5.0)
    for bad in (0.1, 2.5, float("nan"), "fast", None, True):
        with pytest.raises(ValueError, match="preview rate .*0.25 to 2"):
            clock.set_rate(bad, now=8.0)  # type: ignore[arg-type]
    assert clock.rate == 2.0 and clock.position(8.0) == pytest.approx(5.0)


def test_the_status_shows_the_previews_bar_beat_and_counts(bars: Path) -> None:
    preview = score_preview(bars, KIT)
    core = GraphicsCore(GraphicsSettings(latency=0.0), kit=KIT)
    core.load_preview(preview.sequence, preview.impacts, now=10.0, score=preview.score, rate=0.5)
    start = preview.sequence.times[0]  # -1: a second before the first note
    # at half rate, 5.2 wall seconds in, the motion is at 1.6 s: bar 0, beat 3.2 (from 0), at 60 bpm as played
    status = core.status(15.2)
    where = bar_beat(preview.score, start + 2.6)
    assert where is not None and (where.bar, where.beat) == (0, pytest.approx(3.2))
    assert status["score"] == {"bar": 0, "beat": 3.2, "tempo_bpm": 60.0, "beat_unit": 1.0}
    # by 1.6 s: hi-hat eighths 0 to 1.5 s (7), snare 0.5 and 1.5 s, kick 0 and 1 s
    assert status["preview"] == {"rate": 0.5, "poses": len(preview.sequence.times), "strokes": 24,
                                 "played": 11, "laps": 0}
    assert core.status(11.0)["score"] is None  # before the first beat: nothing to show yet
    # faster from then on: at rate 2, a second later the motion is at 3.6 s, bar 1 beat 3.2, 240 bpm as played
    core.set_preview_rate(2.0, 15.2)
    assert core.status(16.2)["score"] == {"bar": 1, "beat": 3.2, "tempo_bpm": 240.0, "beat_unit": 1.0}
    view = core.take_page_messages()[-1]
    assert view["type"] == "view" and view["control"] == "preview_rate" and view["preview_rate"] == 2.0
    # the live view shows what physics' score player sends, not the preview's
    core.handle(GraphicsMode(mode="live"), 16.2, "pd")
    assert core.status(16.2)["score"] is None and core.status(16.2)["preview"] is None


def test_without_a_preview_a_rate_is_refused_and_counted() -> None:
    core = GraphicsCore(GraphicsSettings(latency=0.0), kit=KIT)
    server = ViewServer(core)
    reply = server.handle_page_message('{"type": "preview_rate", "rate": 0.5}')
    assert reply is not None and reply["type"] == "refused" and reply["control"] == "preview_rate"
    assert "no preview is loaded" in reply["error"]
    assert server.counters["page_errors"] == 1
    assert core.view_json()["preview_rate"] is None


def test_the_page_message_changes_the_rate_and_a_bad_one_is_refused(bars: Path) -> None:
    core = make_core(GraphicsNodeSettings(preview_score=str(bars), preview_rate=0.5), None)  # type: ignore[arg-type]
    assert core.preview_clock.rate == 0.5 and core.view_json()["preview_rate"] == 0.5
    server = ViewServer(core, clock=lambda: 3.0)
    assert server.handle_page_message('{"type": "preview_rate", "rate": 0.25}') is None
    assert core.preview_clock.rate == 0.25
    reply = server.handle_page_message('{"type": "preview_rate", "rate": 4}')
    assert reply is not None and "preview rate 4" in reply["error"] and server.counters["page_errors"] == 1
    assert core.preview_clock.rate == 0.25


def test_a_rate_out_of_range_on_the_command_line_exits_2(bars: Path) -> None:
    result = subprocess.run(
        [sys.executable, "-m", "services.graphics.node", "--no-discovery", "--no-oscquery", "--host", "127.0.0.1",
         "--port", "0", "--http-port", "0", "--preview-score", str(bars), "--preview-rate", "3"],
        cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert result.returncode == 2, result.stderr
    assert result.stderr.startswith("batteur graphics: error: ") and "preview_rate" in result.stderr
    assert "Traceback" not in result.stderr


STATUS = "() => document.getElementById('status-body').innerText"


@needs_browser
@pytest.mark.parametrize(("width", "height"), [(1000, 600), (375, 667)])
def test_the_page_shows_where_the_preview_is_and_slows_it_down(bars: Path, tmp_path: Path, width: int,
                                                                height: int) -> None:
    node = GraphicsNodeProcess(tmp_path, latency=0.0, extra=[
        "--no-oscquery", "--preview-score", str(bars), "--preview-rate", "0.5", "--clock-master", "self"])
    node.start()
    try:
        with open_page(node.url, 5, width, height, wait_for_status=True) as (page, errors):
            if width < height:  # a phone held upright: the status panel starts folded
                page.click("#status-toggle")
            # half speed: the written 120 bpm plays at 60, and the bar and beat count on (not "score –")
            page.wait_for_function(f"({STATUS})().includes('bpm')", timeout=20000)
            text = page.evaluate(STATUS)
            assert "@ 60 bpm" in text and "preview \u00d70.5" in text and "strokes " in text, text
            assert "poses 0" not in text and "impacts 0" not in text, text
            assert page.is_visible("#preview-rate") and page.input_value("#preview-rate") == "0.5"
            page.select_option("#preview-rate", "1")
            page.wait_for_function(f"({STATUS})().includes('@ 120 bpm')", timeout=10000)
            assert "preview \u00d71 " in page.evaluate(STATUS) + " "
            # the speed select keeps the panels apart and inside the window (the phone layout holds)
            boxes = page.evaluate("ids => ids.map(id => { const r = document.getElementById(id)"
                                  ".getBoundingClientRect(); return [r.left, r.top, r.right, r.bottom]; })",
                                  ["status", "toolbar", "plot", "preview-rate-box"])
            status, toolbar, plot, rate = boxes
            for a, b in ((status, toolbar), (status, plot), (toolbar, plot)):
                assert not (a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]), f"{a} overlaps {b}"
            assert toolbar[0] <= rate[0] and rate[2] <= toolbar[2] and rate[3] <= toolbar[3]
            assert max(box[2] for box in boxes) <= width and min(box[0] for box in boxes) >= 0
            page.screenshot(path=str(tmp_path / f"preview-rate-{width}x{height}.png"))
            assert errors == []
    finally:
        node.close()


def test_bars_are_found_as_the_status_counts_them(bars: Path) -> None:
    preview = score_preview(bars, KIT)
    assert parse_bars("2") == (2, 2) and parse_bars(" 1-2 ") == (1, 2)
    for bad in ("0", "2-1", "two", "1-", ""):
        with pytest.raises(ValueError, match="--preview-bars"):
            parse_bars(bad)
    assert bar_span(preview.score, 1, 1) == pytest.approx((0.0, 2.0))
    assert bar_span(preview.score, 2, 2) == pytest.approx((2.0, 4.0))
    assert bar_span(preview.score, 3, 4) == pytest.approx((4.0, 8.0))  # past the written bars, bars as long go on
    for first, last in ((1, 1), (2, 2), (3, 4)):  # the inverse of what the status shows
        start, end = bar_span(preview.score, first, last)
        where = bar_beat(preview.score, start + 1e-6)
        assert where is not None and (where.bar, round(where.beat, 3)) == (first - 1, 0.0)
        assert bar_beat(preview.score, end - 1e-6).bar == last - 1  # type: ignore[union-attr]


def test_a_bar_range_loops_without_a_pause(bars: Path) -> None:
    settings = GraphicsNodeSettings(preview_score=str(bars), preview_bars="2", preview_rate=0.5)
    core = make_core(settings, None)  # type: ignore[arg-type]
    assert (core.preview_clock.start, core.preview_clock.span, core.preview_clock.pause) == (2.0, 2.0, 0.0)
    # at half rate a lap of bar 2 takes 4 s; the status never leaves bar 2 (index 1) and counts its 12 strokes
    for wall in (0.0, 1.0, 3.9, 4.1, 9.0):
        status = core.status(wall)
        assert status["score"]["bar"] == 1, (wall, status["score"])
        assert status["preview"]["strokes"] == 12
    assert core.status(3.9)["preview"]["played"] == 12
    assert core.status(4.1)["preview"]["played"] == 2  # the next lap's downbeat: hi-hat and kick
    assert core.status(9.0)["preview"]["laps"] == 2


def test_bad_bar_ranges_exit_2(bars: Path, tmp_path: Path) -> None:
    base = [sys.executable, "-m", "services.graphics.node", "--no-discovery", "--no-oscquery", "--host", "127.0.0.1",
            "--port", "0", "--http-port", "0"]
    cases = [
        (["--preview-score", str(bars), "--preview-bars", "5"], "--preview-bars 5: the score has 2 bars"),
        (["--preview-score", str(bars), "--preview-bars", "2-3"], "--preview-bars 2-3: the score has 2 bars"),
        (["--preview-score", str(bars), "--preview-bars", "2-x"], "a bar or a range of bars from 1"),
        (["--preview", str(tmp_path / "p.npz"), "--preview-bars", "1"], "give --preview-score SCORE with it"),
    ]
    for extra, message in cases:
        result = subprocess.run([*base, *extra], cwd=ROOT, capture_output=True, text=True, timeout=60)
        assert result.returncode == 2, result.stderr
        last = result.stderr.splitlines()[-1]  # bars past the score: known once it is read (after posing's log)
        assert last.startswith("batteur graphics: error: ") and message in last, result.stderr
        assert "Traceback" not in result.stderr


def test_a_preview_loaded_without_a_time_starts_when_first_shown() -> None:
    # the node loads the preview before its clock runs: anchored at rig time 0, a viewer started an hour into a rig
    # showed lap 424, mid-bar
    clock = PreviewClock(start=-1.0, span=5.0)
    assert clock.position(3600.0) == -1.0 and clock.lap(3600.0) == 0
    assert clock.position(3601.5) == pytest.approx(0.5)
    clock.shift(2.0)  # a rig-clock step after the start: the motion shown stays where it was
    assert clock.position(3603.5) == pytest.approx(0.5)
