"""A phone held upright (chromium, headless): the panels left the drummer little room.

In a 375x667 window the status panel (five lines and the node table) and the toolbar (its eight layer ticks on two
lines) took the top 190 px, over the drummer's head, and the tip-height plot the bottom 160 px, over the feet and the
kick: nearly half the window. In a narrow upright window the status panel now starts folded to its first line (the
connection; the stale-poses warning still shows), the layer ticks fold behind a *layers* button, and the plot is
smaller; a tap on either unfolds it. A laptop's window keeps everything open, as before.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from .conftest import GraphicsNodeProcess, needs_browser, open_page, project

PANELS = "ids => ids.map(id => { const r = document.getElementById(id).getBoundingClientRect(); " \
         "return [r.left, r.top, r.right, r.bottom]; })"
"""Page script: the bounding boxes (left, top, right, bottom; CSS pixels) of the elements with these ids."""

DRUMMER = """() => { const s = window.batteur, p = s.lastFrame.p, pts = [];
  s.names.forEach((name, i) => { if (name.startsWith('kit.')) return;
    pts.push([name, p[i * 7], p[i * 7 + 1], p[i * 7 + 2]]);
    if (/head/.test(name)) pts.push(['top of ' + name, p[i * 7], p[i * 7 + 1], p[i * 7 + 2] + 0.19]); });
  const boxes = ['status', 'toolbar', 'plot'].map(id => { const el = document.getElementById(id);
    const r = el.getBoundingClientRect(); return [id, r.left, r.top, r.right, r.bottom, el.offsetParent !== null]; });
  return { pts, boxes, eye: s.camera.position.toArray(), target: s.controls.target.toArray(), fov: s.camera.fov }; }"""
"""Page script: the drummer's drawn points in the newest frame (every body link, and the top of the head sphere,
0.19 m above the head link), the panels' boxes (and whether each is shown) and the camera, read at one instant."""


def _covered(page: Any, width: int, height: int) -> list[str]:
    """The drummer's points outside the window or under a shown panel, as the page draws them now."""
    seen = page.evaluate(DRUMMER)
    eye, target = np.array(seen["eye"]), np.array(seen["target"])
    bad = []
    for name, *xyz in seen["pts"]:
        x, y = project(np.array(xyz), eye, target, seen["fov"], width, height)
        if not (0 <= x <= width and 0 <= y <= height):
            bad.append(f"{name} at ({x:.0f}, {y:.0f}) is outside the window")
        for box_id, left, top, right, bottom, shown in seen["boxes"]:
            if shown and left <= x <= right and top <= y <= bottom:
                bad.append(f"{name} at ({x:.0f}, {y:.0f}) is under the {box_id} {[left, top, right, bottom]}")
    return bad


PHONES = [(390, 844), (375, 667), (360, 640), (320, 568)]


@needs_browser
@pytest.mark.parametrize(("width", "height"), PHONES)
def test_in_an_upright_phone_no_panel_covers_the_drummer(synthetic_node: GraphicsNodeProcess, width: int,
                                                          height: int) -> None:
    with open_page(synthetic_node.url, 10, width, height, wait_for_status=True) as (page, errors):
        page.screenshot(path=str(synthetic_node.tmp / f"portrait-{width}x{height}.png"))
        assert _covered(page, width, height) == []
        assert errors == []


def _shown(page: Any, selector: str) -> bool:
    return bool(page.eval_on_selector(selector, "el => el.offsetParent !== null"))


@needs_browser
def test_the_folded_panels_open_on_a_tap_and_the_layout_holds(synthetic_node: GraphicsNodeProcess) -> None:
    width, height = 375, 667
    with open_page(synthetic_node.url, 10, width, height, wait_for_status=True) as (page, errors):
        assert _shown(page, "#conn") and not _shown(page, "#status-body")
        assert not _shown(page, "#layers") and _shown(page, "#layers-toggle")
        page.click("#layers-toggle")
        assert _shown(page, "#layers")
        # a tick of the unfolded toolbar can be used (clicked first: the folded status panel does not grow with its
        # figures, so the toolbar under it stays put while the click is aimed)
        page.click("#layers label:has-text('floor') input")
        assert page.evaluate("window.batteur.layers.floor.visible") is False
        page.click("#status-toggle")
        assert _shown(page, "#status-body") and "view" in page.inner_text("#status-body")
        status, toolbar, plot = page.evaluate(PANELS, ["status", "toolbar", "plot"])
        page.screenshot(path=str(synthetic_node.tmp / "portrait-unfolded.png"))
        for a, b in ((status, toolbar), (status, plot), (toolbar, plot)):
            assert not (a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]), f"{a} overlaps {b}"
        assert max(status[2], toolbar[2], plot[2]) <= width and min(status[0], toolbar[0], plot[0]) >= 0
        page.click("#status-toggle")
        page.click("#layers-toggle")
        assert not _shown(page, "#status-body") and not _shown(page, "#layers")
        assert errors == []


@needs_browser
def test_a_laptop_window_keeps_the_panels_open(synthetic_node: GraphicsNodeProcess) -> None:
    with open_page(synthetic_node.url, 10, 1000, 600, wait_for_status=True) as (page, errors):
        assert _shown(page, "#status-body") and _shown(page, "#layers")
        assert not _shown(page, "#layers-toggle")  # the ticks are always there: nothing to unfold
        assert errors == []
