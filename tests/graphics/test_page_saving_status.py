"""Page items of the walkthrough (chromium, headless): save buttons of a node that cannot save, the status panel's
figures, and what "view N fps" counts.

Was: under ``batteur rig`` (no ``--kit-dir``) *save kit* and *save pose* looked usable and answered only after a
press; "pose age 465 ms" wrapped its "ms" onto the next line of the 340 px panel; "view N fps" counted frames
received (118 after a stalled tab caught up), not frames drawn."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from .conftest import GraphicsNodeProcess, needs_browser, open_page


class NoKitDirNode(GraphicsNodeProcess):
    """A synthetic-drummer node started as ``batteur rig`` starts graphics: without ``--kit-dir``."""

    def command(self) -> list[str]:
        cmd = super().command()
        i = cmd.index("--kit-dir")
        return cmd[:i] + cmd[i + 2:]


@pytest.fixture
def no_kit_dir_node(tmp_path: Path) -> Iterator[GraphicsNodeProcess]:
    node = NoKitDirNode(tmp_path, extra=["--synthetic", "--clock-master", "self"])
    node.start()
    try:
        yield node
    finally:
        node.close()


@pytest.fixture
def fast_node(tmp_path: Path) -> Iterator[GraphicsNodeProcess]:
    """A synthetic-drummer node sending 240 frames a second: more than a page draws."""
    node = GraphicsNodeProcess(tmp_path, extra=["--synthetic", "--clock-master", "self", "--rate-hz", "240"])
    node.start()
    try:
        yield node
    finally:
        node.close()


SAVE_STATE = """() => ['kit-save', 'pose-save'].map(id => { const b = document.getElementById(id);
  return { disabled: b.disabled, title: b.title, rowTitle: b.parentElement.title }; })"""


@needs_browser
def test_save_buttons_are_off_and_say_why_when_the_node_cannot_save(no_kit_dir_node: GraphicsNodeProcess) -> None:
    with open_page(no_kit_dir_node.url, 10, 1000, 600) as (page, errors):
        page.click("#edit-toggle")
        page.wait_for_function("document.querySelectorAll('#pose-sliders .slider').length > 0", timeout=10000)
        for button in page.evaluate(SAVE_STATE):
            assert button["disabled"] is True, button
            for title in (button["title"], button["rowTitle"]):
                assert "--kit-dir DIR" in title and "batteur rig: its --kit-dir DIR" in title, button
        page.press("#kit-file", "Enter")  # Enter saves as the button does: told why not, here too
        assert "batteur rig: its --kit-dir DIR" in page.inner_text("#editor-msg")
        page.screenshot(path=str(no_kit_dir_node.tmp / "saving-off.png"))
        assert errors == []


@needs_browser
def test_save_buttons_are_on_when_the_node_can_save(synthetic_node: GraphicsNodeProcess) -> None:
    with open_page(synthetic_node.url, 10, 1000, 600) as (page, errors):
        page.click("#edit-toggle")
        assert all(not b["disabled"] and b["title"] == "" for b in page.evaluate(SAVE_STATE))
        assert errors == []


WRAPPED_FIGURES = r"""() => {
  const panel = document.getElementById('status'), body = document.getElementById('status-body');
  const wrapped = new Set();
  for (let w = 200; w <= 340; w += 2) {
    panel.style.minWidth = panel.style.maxWidth = `${w}px`;
    const walker = document.createTreeWalker(body, NodeFilter.SHOW_TEXT);
    for (let node = walker.nextNode(); node; node = walker.nextNode()) {
      for (const m of node.textContent.matchAll(/\d[\d.]*(\/\d[\d.]*)? (ms|fps|s|Hz)\b/g)) {
        const r = document.createRange();
        r.setStart(node, m.index); r.setEnd(node, m.index + m[0].length);
        const tops = new Set([...r.getClientRects()].map(rect => Math.round(rect.top)));
        if (tops.size > 1) wrapped.add(`${m[0]} at ${w}px`);
      }
    }
  }
  return [...wrapped];
}"""
"""Page script: the figures of the status panel (number and unit) split over two lines, at panel widths 200-340 px."""


@needs_browser
def test_no_figure_of_the_status_panel_wraps_its_unit_onto_the_next_line(
        synthetic_node: GraphicsNodeProcess) -> None:
    with open_page(synthetic_node.url, 10, 1000, 600, wait_for_status=True) as (page, errors):
        page.wait_for_function("window.batteur.status.pose_lag !== null", timeout=10000)
        assert "pose age" in page.inner_text("#status-body")
        assert page.evaluate(WRAPPED_FIGURES) == []
        assert errors == []


COUNT_RAF = """() => new Promise(resolve => { const s = window.batteur; let n = 0; const t0 = performance.now();
  const f0 = s.frames;
  const tick = (now) => { n += 1;
    if (now - t0 < 3000) requestAnimationFrame(tick);
    else resolve({ raf: n * 1000 / (now - t0), received: (s.frames - f0) * 1000 / (now - t0), fps: s.fps }); };
  requestAnimationFrame(tick); })"""
"""Page script: over 3 s, the page's animation frames per second, frames received per second, and its "fps"."""


@needs_browser
def test_view_fps_counts_frames_drawn_not_received(fast_node: GraphicsNodeProcess) -> None:
    with open_page(fast_node.url, 10, 800, 450, wait_for_status=True) as (page, errors):
        rates = page.evaluate(COUNT_RAF)
        # the node sends more than the page can draw, so received and drawn differ (else the test tells nothing)
        assert rates["received"] > rates["raf"] * 1.5, rates
        assert 0 < rates["fps"] <= rates["raf"] * 1.2 + 1, rates
        assert errors == []
