"""The page's own controls in a real browser (Debian's chromium, headless, driven by Playwright).

What a user of the page relies on besides the picture itself: the panels stay
readable in a narrow window, a camera picked on the page stays put when the node
changes something else, and the orbit preset starts from the front.
"""

from __future__ import annotations

import socket
from pathlib import Path
from typing import Any

import pytest

from common.messages import decode
from common.messages.graphics import GraphicsCamera, GraphicsShow, GraphicsTrails
from common.messages.physics import PhysicsPosture, PhysicsReset

from .conftest import CHROMIUM, CHROMIUM_FLAGS, GraphicsNodeProcess, needs_browser, open_page, received_from

PANELS = "ids => ids.map(id => { const r = document.getElementById(id).getBoundingClientRect(); " \
         "return [r.left, r.top, r.right, r.bottom]; })"
"""Page script: the bounding boxes (left, top, right, bottom; CSS pixels) of the elements with these ids."""
SET_SLIDER = "(el, v) => { el.value = v; el.dispatchEvent(new Event('input')); }"
"""Page script: move a range input (el) to v as a user would (an input event)."""
AZIMUTH = "(() => { const c = window.batteur.camera.position, t = window.batteur.controls.target; " \
          "return Math.atan2(c.x - t.x, c.y - t.y) * 180 / Math.PI; })()"
"""Page script: the camera's azimuth about its target, degrees (0: from the front, +y; 90: from +x)."""


def _page(url: str, width: int = 1000, height: int = 600) -> Any:
    """The page once frames are drawn and a status shown: (page, page errors so far)."""
    return open_page(url, 10, width, height, wait_for_status=True)


def _overlap(a: list[float], b: list[float]) -> bool:
    """Whether two boxes (left, top, right, bottom) share any area."""
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


@needs_browser
@pytest.mark.parametrize("width", [1000, 600])
def test_toolbar_and_editor_never_cover_the_status_panel(synthetic_node: GraphicsNodeProcess, width: int) -> None:
    """In a window narrower than status + toolbar (a half-screen browser), the toolbar used to lie over the
    status panel (connection, rig time and score position unreadable) and the open editor over the toolbar."""
    with _page(synthetic_node.url, width, 800) as (page, errors):
        page.click("#edit-toggle")
        page.wait_for_function("window.batteur.poser && window.batteur.poser.joints", timeout=10000)
        status, toolbar, editor = page.evaluate(PANELS, ["status", "toolbar", "editor"])
        page.screenshot(path=str(synthetic_node.tmp / f"panels-{width}.png"))
        assert not _overlap(status, toolbar), f"toolbar {toolbar} covers the status panel {status}"
        assert not _overlap(editor, toolbar), f"editor {editor} covers the toolbar {toolbar}"
        assert not _overlap(editor, status), f"editor {editor} covers the status panel {status}"
        assert max(status[2], toolbar[2], editor[2]) <= width, "a panel runs off the window"
        assert errors == []


@needs_browser
def test_a_camera_picked_on_the_page_stays_when_the_node_changes_something_else(
        synthetic_node: GraphicsNodeProcess) -> None:
    """Any view message (an OSC trails, show, plot, latency or mode) used to put the node's camera back: the
    page's own camera choice jumped back to front. Only a new camera from the node moves it."""
    with _page(synthetic_node.url) as (page, errors):
        page.select_option("#camera-preset", "side")
        assert page.evaluate(AZIMUTH) == pytest.approx(90.0, abs=0.5)
        synthetic_node.send(GraphicsTrails(seconds=3.0))
        page.wait_for_function("window.batteur.view.trails === 3", timeout=10000)
        synthetic_node.send(GraphicsShow(layer="floor", visible=0))
        page.wait_for_function("window.batteur.view.layers.floor === false", timeout=10000)
        assert page.eval_on_selector("#camera-preset", "el => el.value") == "side"
        assert page.evaluate(AZIMUTH) == pytest.approx(90.0, abs=0.5), "the camera left the side view"

        # a camera the node is sent does apply
        synthetic_node.send(GraphicsCamera(preset="free", azimuth_deg=-90.0, elevation_deg=10.0, distance=2.0,
                                           target_x=0.0, target_y=0.35, target_z=0.75))
        page.wait_for_function("window.batteur.view.camera.preset === 'free'", timeout=10000)
        assert page.evaluate(AZIMUTH) == pytest.approx(-90.0, abs=0.5)
        assert page.eval_on_selector("#camera-preset", "el => el.value") == "free"
        assert errors == []


@needs_browser
def test_a_layer_hidden_on_the_page_stays_hidden_when_the_node_changes_something_else(
        synthetic_node: GraphicsNodeProcess) -> None:
    """Unticking a layer on the page holds until the node is sent that layer (not any other control)."""
    with _page(synthetic_node.url) as (page, errors):
        page.click("#layers label:has-text('kit') input")
        assert page.evaluate("window.batteur.view.layers.kit") is False
        synthetic_node.send(GraphicsTrails(seconds=2.0))
        page.wait_for_function("window.batteur.view.trails === 2", timeout=10000)
        assert page.is_checked("#layers label:has-text('kit') input") is False
        assert page.evaluate("window.batteur.view.layers.kit") is False, "the kit came back"
        synthetic_node.send(GraphicsShow(layer="kit", visible=1))  # the node's own word on that layer applies
        page.wait_for_function("window.batteur.view.layers.kit === true", timeout=10000)
        assert page.is_checked("#layers label:has-text('kit') input") is True
        assert errors == []


@needs_browser
def test_the_orbit_preset_starts_from_the_front(synthetic_node: GraphicsNodeProcess) -> None:
    """docs/graphics.md: orbit turns 12 degrees/s from azimuth 0. The page used to turn from the moment it was
    loaded, so picking orbit jumped to wherever that had got to (and two tabs disagreed)."""
    with _page(synthetic_node.url) as (page, errors):
        # a page open for a while (not a whole turn of 30 s, when the old page was by chance at the front again)
        page.wait_for_function("performance.now() % 30000 > 5000 && performance.now() % 30000 < 25000",
                               timeout=30000)
        start = page.evaluate("(() => { const s = document.getElementById('camera-preset'); s.value = 'orbit'; "
                              f"s.dispatchEvent(new Event('change')); return {AZIMUTH}; }})()")
        assert start == pytest.approx(0.0, abs=1.0), f"orbit started at azimuth {start} degrees"
        assert errors == []


@needs_browser
def test_a_looping_preview_draws_on_without_errors(tmp_path: Path) -> None:
    """Each time the preview starts again (as when physics restarts) the frames' time goes back: the trails used
    to be emptied and the tip-height plot then threw (TypeError in the console), losing that frame's kit and
    contact markers."""
    score = Path(__file__).with_name("tiny_score.txt")  # loops every ~3 s: 1 s rest, 0.6 s of notes, 1.5 s
    node = GraphicsNodeProcess(tmp_path, extra=["--preview-score", str(score), "--clock-master", "self"])
    node.start()
    console: list[str] = []
    try:
        with _page(node.url) as (page, errors):
            page.on("console", lambda m: console.append(m.text) if m.type == "error" else None)
            page.evaluate("window.batteur.tMax = -Infinity")
            # until the preview has started again, well after its end
            page.wait_for_function("(() => { const b = window.batteur, t = b.lastFrame.t; "
                                   "b.tMax = Math.max(b.tMax, t); return t < b.tMax - 1; })()",
                                   timeout=30000, polling=50)
            frames = page.evaluate("window.batteur.frames")
            page.wait_for_function(f"window.batteur.frames > {frames + 10}", timeout=10000)
            assert console == [], console
            assert errors == []
            trails = page.evaluate("[...window.batteur.trails.values()].map(t => t.points.length)")
            assert trails and min(trails) >= 1, "a trail is empty after the loop"
    finally:
        node.close()


def _waiting(sock: socket.socket) -> list[Any]:
    """Every message already waiting at ``sock`` (without waiting for more)."""
    out: list[Any] = []
    sock.setblocking(False)
    try:
        while True:
            try:
                out += decode(sock.recv(65536)).messages
            except BlockingIOError:
                return out
    finally:
        sock.settimeout(0.2)


@needs_browser
def test_the_editor_of_one_tab_is_released_when_that_tab_closes(tmp_path: Path) -> None:
    """Two tabs, one editing: another tab opening and closing its editor used to end the first tab's edit (the
    drawn body went back to the stream), and closing the editing tab left physics holding the posture as long
    as any other tab stayed open. The body is released when the last editor closes, or its tab does."""
    from playwright.sync_api import sync_playwright

    physics = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)  # stands in for the physics node
    physics.bind(("127.0.0.1", 0))
    physics.settimeout(0.2)
    node = GraphicsNodeProcess(tmp_path, extra=["--synthetic", "--clock-master", "self",
                                                "--peer", f"physics=127.0.0.1:{physics.getsockname()[1]}"])
    node.start()
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_FLAGS)
            context = browser.new_context(viewport={"width": 1000, "height": 600})
            editing, other = context.new_page(), context.new_page()
            errors: list[str] = []
            for page in (editing, other):
                page.on("pageerror", lambda e: errors.append(str(e)))
                page.goto(node.url)
                page.wait_for_function("window.batteur && window.batteur.frames > 5", timeout=20000)
            editing.click("#edit-toggle")
            editing.wait_for_function("window.batteur.poser && window.batteur.poser.joints", timeout=10000)
            editing.select_option("#pose-joint", "right_elbow")
            editing.eval_on_selector("#pose-sliders input", SET_SLIDER, "100")
            assert received_from(physics, PhysicsPosture), "no posture reached physics"
            edited = "!window.batteur.names.includes('right_stick_tip')"  # physics' body drawn, not the figure
            editing.wait_for_function(edited, timeout=10000)

            other.click("#edit-toggle")
            other.wait_for_function("window.batteur.poser && window.batteur.poser.joints", timeout=10000)
            other.click("#edit-toggle")  # this tab's editor closes; the first tab still edits
            # a bad save's error reply comes after the node handled the close (one connection, in order)
            other.evaluate("window.batteur.ws.send(JSON.stringify({type: 'save_pose', name: 'not a pose'}))")
            other.wait_for_function("document.getElementById('editor-msg').textContent.includes('not saved')",
                                    timeout=10000)
            frames = editing.evaluate("window.batteur.frames")
            editing.wait_for_function(f"window.batteur.frames > {frames + 10}", timeout=10000)
            assert editing.evaluate(edited), "the first tab's edited body is no longer drawn"
            assert not any(isinstance(m, PhysicsReset) for m in _waiting(physics)), "physics was released"

            editing.close()  # closing the editing tab releases the body although another tab stays
            assert received_from(physics, PhysicsReset), "closing the editing tab sent no /batteur/physics/reset"
            assert errors == []
            browser.close()
    finally:
        node.close()
        physics.close()


@needs_browser
def test_a_stopped_node_leaves_the_status_greyed_out_until_it_is_back(synthetic_node: GraphicsNodeProcess) -> None:
    """When the node (the rig) stops, the panel used to keep showing the last rig time and nodes as if live;
    it says it is reconnecting and greys out what it last heard, until the node is back."""
    with _page(synthetic_node.url) as (page, errors):
        assert page.eval_on_selector("#status-body", "el => el.classList.contains('stale')") is False
        synthetic_node.stop()
        page.wait_for_function("window.batteur.connected === false", timeout=10000)
        assert page.inner_text("#conn").startswith("reconnecting")
        assert page.eval_on_selector("#status-body", "el => el.classList.contains('stale')") is True
        assert page.eval_on_selector("#status-body", "el => getComputedStyle(el).opacity") != "1"
        synthetic_node.start()
        page.wait_for_function("window.batteur.connected && window.batteur.connects >= 2", timeout=15000)
        page.wait_for_function("!document.getElementById('status-body').classList.contains('stale')",
                               timeout=10000)
        assert errors == []
