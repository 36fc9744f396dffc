"""The kit editor and the tip-height plot as a user meets them, in Debian's chromium (Playwright), each against
the defect it was written for: kit values between the old slider steps (5 mm, 1 degree) kept and typed exactly,
a slider that can be dragged, a kit redrawn without leaking GPU buffers, a save the node cannot get, a file
name the node must refuse, and a tip-height plot that says it has nothing to draw.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from common.kit import Kit, load_kit, save_kit
from services.graphics.core import GraphicsCore, GraphicsSettings
from services.graphics.figure import SyntheticDrummer
from services.graphics.server import ViewServer

from .conftest import GraphicsNodeProcess, needs_browser, open_page
from .test_page import PoseSender

FINE_X_M, FINE_YAW_DEG = 0.1234, 12.34
"""The crash's position x and yaw in the test kit: between the old slider steps (5 mm, 1 degree)."""
ROW_VALUES = "rows => rows.map(r => [r.firstChild.textContent, r.children[0].value, r.children[1].value])"
"""Page script: each kit row's (label, slider value, number field value)."""
CRASH = "window.batteur.kit.objects.find(o => o.id === 'crash')"
"""Page expression: the crash as the page holds the kit."""
SET_SLIDER = "(el, v) => { el.value = v; el.dispatchEvent(new Event('input')); }"
"""Page script: move a range input (el) to v as a user would (an input event)."""


def _fine_kit(path: Path) -> Kit:
    """The default kit with the crash at x = 0.1234 m, yaw 12.34 degrees, saved to ``path``."""
    data = load_kit().model_dump(mode="json")
    crash = next(o for o in data["objects"] if o["id"] == "crash")
    crash["position"][0], crash["rotation_deg"][2] = FINE_X_M, FINE_YAW_DEG
    kit = Kit.model_validate(data)
    save_kit(kit, path)
    return kit


@pytest.fixture
def crash_in_editor(tmp_path: Path) -> Iterator[tuple[Any, GraphicsNodeProcess, Kit]]:
    """A node drawing the fine kit (no poses), the page with the editor open on the crash."""
    kit = _fine_kit(tmp_path / "fine.yaml")
    node = GraphicsNodeProcess(tmp_path, extra=["--clock-master", "self", "--kit", str(tmp_path / "fine.yaml")])
    node.start()
    try:
        with open_page(node.url, -1) as (page, errors):
            page.wait_for_function("window.batteur.kit && window.batteur.connected", timeout=10000)
            page.click("#edit-toggle")
            page.select_option("#kit-object", "crash")
            yield page, node, kit
            assert errors == []
    finally:
        node.close()


def _type(page: Any, row: int, text: str) -> None:
    """Type ``text`` into the number field of kit row ``row`` (0 pos x ... 6 radius) and press Enter."""
    field = page.locator("#kit-sliders input[type=number]").nth(row)
    field.fill(text)
    field.press("Enter")


def _save(page: Any, node: GraphicsNodeProcess, name: str) -> Kit:
    """Save the kit as ``name`` from the page and load the file the node wrote."""
    page.fill("#kit-file", name)
    page.click("#kit-save")
    page.wait_for_function("document.getElementById('editor-msg').textContent.startsWith('saved')", timeout=10000)
    return load_kit(node.tmp / "kits" / name)


@needs_browser
def test_a_kit_value_between_slider_steps_is_kept_when_another_is_changed(
        crash_in_editor: tuple[Any, GraphicsNodeProcess, Kit]) -> None:
    """The rows showed 0.123 and 12.340 and their sliders sat on 0.125 and 12 (the nearest steps): showing the
    row now shows the value as loaded, and a kit saved after changing another field keeps it to the digit."""
    page, node, loaded = crash_in_editor
    rows = page.eval_on_selector_all("#kit-sliders .slider", ROW_VALUES)
    assert [r[0] for r in rows] == ["pos x", "pos y", "pos z", "roll", "pitch", "yaw", "radius"]
    assert rows[0][1:] == [str(FINE_X_M), str(FINE_X_M)]
    assert rows[5][1:] == [str(FINE_YAW_DEG), str(FINE_YAW_DEG)]

    _type(page, 4, "3.5")  # pitch: another field of the same object
    saved = _save(page, node, "pitched.yaml")
    crash = saved.object("crash")
    assert crash.position[0] == FINE_X_M and crash.rotation_deg[2] == FINE_YAW_DEG
    assert crash.rotation_deg[1] == 3.5
    expected = loaded.model_dump()
    next(o for o in expected["objects"] if o["id"] == "crash")["rotation_deg"] = (15.0, 3.5, FINE_YAW_DEG)
    assert saved.model_dump() == {**expected, "name": saved.name}  # every other number as loaded


@needs_browser
def test_a_typed_kit_value_is_set_exactly(crash_in_editor: tuple[Any, GraphicsNodeProcess, Kit]) -> None:
    """No value off the 5 mm / 1 degree grid could be set: a typed one is now the kit's and the saved file's,
    exactly, and shown whole; a radius the kit model refuses is brought into its range, not sent to fail."""
    page, node, _ = crash_in_editor
    _type(page, 0, "0.98765")
    _type(page, 5, "-33.333")
    _type(page, 6, "0")
    assert page.evaluate(f"[{CRASH}.position[0], {CRASH}.rotation_deg[2], {CRASH}.radius]") == [0.98765, -33.333,
                                                                                                0.001]
    rows = page.eval_on_selector_all("#kit-sliders .slider", ROW_VALUES)
    assert rows[0][1:] == ["0.98765", "0.98765"] and rows[5][1:] == ["-33.333", "-33.333"]
    _type(page, 1, "-0.123456")  # every digit fits in its field (the 60 px readout column cut them off)
    _type(page, 3, "-123.45")
    widths = page.eval_on_selector_all("#kit-sliders input[type=number]", "els => els.map(e => [e.scrollWidth, "
                                       "e.clientWidth])")
    assert all(scroll <= client for scroll, client in widths), widths
    crash = _save(page, node, "typed.yaml").object("crash")
    assert (crash.position[0], crash.position[1], crash.rotation_deg[0], crash.rotation_deg[2], crash.radius) == (
        0.98765, -0.123456, -123.45, -33.333, 0.001)


@needs_browser
def test_a_kit_slider_can_be_dragged(crash_in_editor: tuple[Any, GraphicsNodeProcess, Kit]) -> None:
    """Every step of a slider rebuilt the rows, which ended the drag after its first step (the drum stayed
    where the first pixel put it): a drag now moves the crash all the way, on a 1 mm grid; pressing the yaw
    slider's thumb without moving leaves 12.34."""
    page, _, _ = crash_in_editor
    box = page.locator("#kit-sliders input[type=range]").first.bounding_box()
    x0, y = box["x"] + 0.25 * box["width"], box["y"] + box["height"] / 2
    page.mouse.move(x0, y)
    page.mouse.down()
    seen = []
    for k in range(1, 11):
        page.mouse.move(x0 + 4 * k, y)
        seen.append(page.evaluate(f"{CRASH}.position[0]"))
    page.mouse.up()
    assert seen[-1] - seen[0] > 0.5  # 36 px of a 3 m slider about 130 px wide (was 0: stuck after one step)
    assert all(b > a for a, b in zip(seen, seen[1:], strict=False)), seen
    assert all(abs(v * 1000 - round(v * 1000)) < 1e-9 for v in seen), seen

    yaw = page.locator("#kit-sliders input[type=range]").nth(5).bounding_box()
    thumb = yaw["height"]  # chromium's thumb is about as wide as the slider is high
    at = yaw["x"] + thumb / 2 + (FINE_YAW_DEG + 180) / 360 * (yaw["width"] - thumb)
    page.mouse.click(at, yaw["y"] + yaw["height"] / 2)
    assert page.evaluate(f"{CRASH}.rotation_deg[2]") == FINE_YAW_DEG


@needs_browser
def test_moving_a_kit_object_does_not_leak_gpu_buffers(crash_in_editor: tuple[Any, GraphicsNodeProcess, Kit]) -> None:
    """Each slider step redraws the kit; the old kit's geometries were dropped without being freed, so a long
    drag piled up GPU buffers (about 60 per step). Their count now stays as it was."""
    page, _, _ = crash_in_editor
    page.wait_for_function("window.batteur.rendered > 2")
    before = page.evaluate("window.batteur.renderer.info.memory.geometries")
    slider = page.locator("#kit-sliders input[type=range]").first
    for k in range(30):
        slider.evaluate(SET_SLIDER, str(round(-0.3 + 0.01 * k, 3)))
    rendered = page.evaluate("window.batteur.rendered")
    page.wait_for_function(f"window.batteur.rendered > {rendered + 2}")
    assert page.evaluate("window.batteur.renderer.info.memory.geometries") == before


@needs_browser
def test_a_save_the_node_cannot_get_says_so(crash_in_editor: tuple[Any, GraphicsNodeProcess, Kit]) -> None:
    """With the node stopped, **save kit** and **save pose** did nothing at all (the message was dropped): the
    editor now says it did not save. A bad file name is refused with what a name may be."""
    page, node, _ = crash_in_editor
    page.fill("#kit-file", "../outside.yaml")
    page.click("#kit-save")
    page.wait_for_function("document.getElementById('editor-msg').textContent.startsWith('not saved')")
    assert "file name" in page.inner_text("#editor-msg")
    node.stop()
    page.wait_for_function("!window.batteur.connected", timeout=10000)
    page.fill("#kit-file", "later.yaml")
    page.click("#kit-save")
    message = page.locator("#editor-msg")
    assert message.inner_text().startswith("not saved") and "not connected" in message.inner_text()
    assert "bad" in (message.get_attribute("class") or "")
    page.evaluate("document.getElementById('editor-msg').textContent = ''")
    page.click("#pose-save")  # the editor's body came from the node when it opened
    assert "not connected" in message.inner_text()


def _lit_pixels(page: Any) -> int:
    """Pixels of the plot canvas brighter than its grey box (text or curves drawn on it)."""
    data = page.evaluate("""() => { const c = document.getElementById('plot');
      return Array.from(c.getContext('2d').getImageData(0, 0, c.width, c.height).data); }""")
    rgba = np.asarray(data, dtype=np.uint8).reshape(-1, 4)
    return int((rgba[:, :3].max(axis=1) > 100).sum())


@needs_browser
def test_the_tip_height_plot_says_when_it_has_nothing_to_draw(graphics_node: GraphicsNodeProcess) -> None:
    """With no poses the plot was an empty grey box: it now says there are no strokes yet, and stops saying so
    when poses with stick tips arrive."""
    with open_page(graphics_node.url, -1) as (page, errors):
        page.wait_for_function("window.batteur.rendered > 2 && window.batteur.connected", timeout=10000)
        assert page.get_attribute("#plot", "aria-label") == "stick tip height plot: no strokes yet"
        assert _lit_pixels(page) > 30  # the words are drawn (the old box had none)

        sender = PoseSender(graphics_node, SyntheticDrummer(strokes={}, duration=0.0).pose(0.0))
        try:
            page.wait_for_function("window.batteur.plot.length > 5", timeout=15000)
            page.wait_for_function("window.batteur.plotNotice === ''", timeout=10000)
        finally:
            sender.stop()
        assert page.get_attribute("#plot", "aria-label") == "stick tip height plot"
        assert errors == []


@pytest.mark.parametrize("name", ["kit.yaml\n", "kit.json\n"])
def test_a_file_name_with_a_line_break_is_refused(tmp_path: Path, name: str) -> None:
    """The file-name check ended in ``$``, which also matches before a final line break: a page (or any same-origin
    WebSocket client) could write ``kit.yaml\\n`` into the kit directory, a file no one can name back. Refused now."""
    server = ViewServer(GraphicsCore(GraphicsSettings(latency=0.0, clock="rig")), kit_dir=tmp_path)
    kit = load_kit().model_dump(mode="json")
    reply = server.handle_page_message(json.dumps({"type": "save_kit", "file": name, "kit": kit}))
    assert reply is not None and reply["ok"] is False and "file name" in reply["error"]
    assert list(tmp_path.iterdir()) == []
    reply = server.handle_page_message(json.dumps({"type": "save_kit", "file": name.strip(), "kit": kit}))
    assert reply is not None and reply["ok"] is True
    assert load_kit(tmp_path / name.strip()) == load_kit()


@needs_browser
def test_a_joint_angle_is_shown_whole(crash_in_editor: tuple[Any, GraphicsNodeProcess, Kit]) -> None:
    """The pose rows' 60 px fields cut an angle of three digits (a knee bends to -163 degrees) to "163.13" or
    "-163.1", and every row was 15 px wider than the editor (its sliders' default width): every digit now
    shows and the rows fit."""
    page, _, _ = crash_in_editor
    page.wait_for_function("window.batteur.poser", timeout=10000)
    page.select_option("#pose-joint", "left_knee")
    field = page.locator("#pose-sliders input[type=number]").first
    field.fill("-150.25")
    field.press("Enter")
    assert field.input_value() == "-150.25"
    widths = page.eval_on_selector_all("#pose-sliders input[type=number]", "els => els.map(e => [e.scrollWidth, "
                                       "e.clientWidth])")
    assert all(scroll <= client for scroll, client in widths), widths
    rows = page.eval_on_selector_all("#editor, #editor .slider", "els => els.map(e => [e.scrollWidth, e.clientWidth])")
    assert all(scroll <= client for scroll, client in rows), rows  # no row wider than the editor (15 px were)
