"""What a user walking through the page met (chromium, headless): a phone-sized window, physics stopping.

In a phone held sideways (667x375) the tip-height plot lay over the toolbar (the layer ticks under it could not
be clicked), and with the editor open it was pushed off the left edge of the window. When physics stopped, the
page went on drawing the last pose and saying *connected*: nothing told the user why the drummer stood still.
"""

from __future__ import annotations

import pytest

from services.graphics.figure import LINK_NAMES, SyntheticDrummer

from .conftest import GraphicsNodeProcess, needs_browser, open_page
from .test_page import PoseSender

PANELS = "ids => ids.map(id => { const r = document.getElementById(id).getBoundingClientRect(); " \
         "return [r.left, r.top, r.right, r.bottom]; })"
"""Page script: the bounding boxes (left, top, right, bottom; CSS pixels) of the elements with these ids."""


def _overlap(a: list[float], b: list[float]) -> bool:
    """Whether two boxes (left, top, right, bottom) share any area."""
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


@needs_browser
@pytest.mark.parametrize(("width", "height"), [(667, 375), (568, 320), (375, 667)])
def test_in_a_phone_window_the_plot_covers_no_panel_and_stays_in_the_window(
        synthetic_node: GraphicsNodeProcess, width: int, height: int) -> None:
    with open_page(synthetic_node.url, 10, width, height, wait_for_status=True) as (page, errors):
        for editing in (False, True):
            if editing:
                page.click("#edit-toggle")
                page.wait_for_function("document.querySelectorAll('#pose-sliders .slider').length === 3",
                                       timeout=10000)
            status, toolbar, editor, plot = page.evaluate(PANELS, ["status", "toolbar", "editor", "plot"])
            page.screenshot(path=str(synthetic_node.tmp / f"phone-{width}x{height}-{editing}.png"))
            where = f"({width}x{height}, editor {'open' if editing else 'closed'})"
            assert not _overlap(plot, toolbar), f"plot {plot} covers the toolbar {toolbar} {where}"
            assert not _overlap(plot, status), f"plot {plot} covers the status panel {status} {where}"
            if editing:
                assert not _overlap(plot, editor), f"plot {plot} covers the editor {editor} {where}"
            assert plot[0] >= 0 and plot[2] <= width and plot[3] <= height, f"plot {plot} is cut off {where}"
            assert plot[3] - plot[1] >= 40, f"plot {plot} too small to read {where}"
        assert errors == []


@needs_browser
def test_the_page_says_when_physics_stops_sending_poses(graphics_node: GraphicsNodeProcess) -> None:
    """The node holds the newest pose when poses stop (docs/graphics.md), so frames keep coming: the page must
    say from the pose age that physics went quiet, and stop saying it when poses come again."""
    pose = SyntheticDrummer().pose(0.0)
    sender = PoseSender(graphics_node, pose)
    try:
        with open_page(graphics_node.url, 10, 1000, 600, wait_for_status=True) as (page, errors):
            page.wait_for_function("window.batteur.status.pose_lag !== null", timeout=10000)
            assert page.is_visible("#stale-poses") is False
            sender.stop()
            page.wait_for_function("window.batteur.status.pose_lag > 3", timeout=20000)
            page.wait_for_function("document.getElementById('stale-poses') && "
                                   "!document.getElementById('stale-poses').classList.contains('hidden')",
                                   timeout=15000)
            text = page.inner_text("#stale-poses")
            page.screenshot(path=str(graphics_node.tmp / "physics-quiet.png"))
            assert "no poses from physics" in text and "last pose" in text, text
            assert page.inner_text("#conn") == "connected"  # the node is there; physics is not
            sender = PoseSender(graphics_node, pose)
            page.wait_for_function("window.batteur.status.pose_lag !== null && window.batteur.status.pose_lag < 1",
                                   timeout=20000)
            page.wait_for_function("document.getElementById('stale-poses').classList.contains('hidden')",
                                   timeout=15000)
            assert errors == []
    finally:
        sender.stop()


PLOT_ROWS = """(band) => {
  const c = document.getElementById('plot'), ctx = c.getContext('2d');
  const d = ctx.getImageData(c.width - band, 0, band - 10, c.height).data, w = band - 10;
  const rows = [];
  for (let y = 0; y < c.height; y++) {
    let bright = 0;
    for (let x = 0; x < w; x++) { const i = (y * w + x) * 4; if (Math.max(d[i], d[i + 1], d[i + 2]) > 100) bright++; }
    rows.push(bright / w);
  }
  return rows;
}"""
"""Page script: per row of the tip-height plot, the share of bright pixels (traces, legend) in its right ``band``
px (the legend's columns, less a 10 px margin)."""


@needs_browser
def test_a_high_stick_tip_is_not_drawn_through_the_plot_legend(graphics_node: GraphicsNodeProcess) -> None:
    """The legend (link names) sits top right of the plot; a stick tip held near the top of the plotted range (1.5
    m of the default 0.5..1.6) was drawn straight through the names. The traces now stay under the legend."""
    pose = SyntheticDrummer().pose(0.0)
    names = list(LINK_NAMES)
    pose[names.index("left_stick_tip"), 2] = 1.55
    pose[names.index("right_stick_tip"), 2] = 1.50
    sender = PoseSender(graphics_node, pose)
    try:
        with open_page(graphics_node.url, 10, 1000, 600, wait_for_status=True) as (page, errors):
            page.wait_for_function("window.batteur.plot.length > 30", timeout=20000)
            # The traces grow leftwards from the plot's right edge; wait until they span the legend's band (a slow
            # machine draws fewer frames, so a sample count alone left them short of it).
            page.wait_for_function(f"({PLOT_ROWS})(90).some((share) => share > 0.8)", timeout=20000)
            page.screenshot(path=str(graphics_node.tmp / "plot-legend.png"))
            rows = page.evaluate(PLOT_ROWS, 90)
            traces = [y for y, share in enumerate(rows) if share > 0.8]  # a flat trace: a whole row of the band
            text = [y for y, share in enumerate(rows) if 0 < share < 0.5 and y < len(rows) // 2]  # the names
            assert traces and text, (traces, text)
            assert min(traces) > max(text), f"a trace (rows {traces}) crosses the legend (rows {text})"
            assert errors == []
    finally:
        sender.stop()


WATCH_BACK_STEP = """() => { const s = window.batteur; let last = -Infinity; s.backStep = null;
  s.ws.addEventListener('message', (ev) => { const m = JSON.parse(ev.data);  // after the page's own handler
    if (m.type !== 'frame') return;
    if (m.t < last && s.backStep === null) s.backStep = { from: last, to: m.t, plotFrom: s.plot[0][0] };
    last = m.t; }); }"""
"""Page script: record the first frame whose time goes back, and where the tip-height plot starts just after."""

STEP_BACK = """(step) => { const s = window.batteur, m = { ...s.lastFrame, t: s.lastFrame.t - step };
  s.ws.dispatchEvent(new MessageEvent('message', { data: JSON.stringify(m) })); }"""
"""Page script: hand the page a copy of the newest frame ``step`` s earlier, as the node's stream would send it."""


@needs_browser
def test_a_small_step_back_of_the_view_clock_keeps_the_plot(graphics_node: GraphicsNodeProcess) -> None:
    """The tip-height plot was emptied whenever a frame's time went back at all: on a loaded rig (the view clock
    stepping back a few hundred ms now and then) it showed only the last second or so of its 4 s. A step back
    smaller than the plot's window now drops only the points after the new time. (The node's auto clock no
    longer steps back by less than 0.5 s, test_clock_slew.py; the frame is handed to the page here, as a
    preview looping or a clock stepping on another node would send it.)"""
    sender = PoseSender(graphics_node, SyntheticDrummer().pose(0.0))
    try:
        with open_page(graphics_node.url, 10, 1000, 600, wait_for_status=True) as (page, errors):
            page.evaluate(WATCH_BACK_STEP)
            page.wait_for_function("window.batteur.plot.length > 2 && window.batteur.lastFrame.t - "
                                   "window.batteur.plot[0][0] > 1.5", timeout=20000)
            page.evaluate(STEP_BACK, 0.4)
            page.wait_for_function("window.batteur.backStep !== null", timeout=30000)
            step = page.evaluate("window.batteur.backStep")
            assert step["from"] - step["to"] < 0.5, step  # a small step, not a restart
            assert step["to"] - step["plotFrom"] > 1.0, f"the plot was emptied by a {step['from'] - step['to']} s step"
            assert errors == []
    finally:
        sender.stop()
