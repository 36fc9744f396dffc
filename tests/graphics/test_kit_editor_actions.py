"""The kit and pose editor as a user meets it (Debian's chromium, Playwright), each against the defect it was
written for: the *node's kit changed* notice was hidden with the editor, there was no way to mirror the kit for a
left-handed drummer, contact markers were drawn on the saved kit rather than the kit on screen, Enter in the
pose-name field did not save, and a slider's arrow keys stepped 1 % of its span (3 cm of a position).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import pytest

from common.gesture.keyposes import KeyPoses
from common.kit import Kit
from common.messages import Impact
from services.graphics.figure import SyntheticDrummer
from services.graphics.scene import impact_point

from .conftest import GraphicsNodeProcess, needs_browser
from .test_kit_editor import CRASH, FINE_X_M, FINE_YAW_DEG, ROW_VALUES, _save, _type, crash_in_editor  # noqa: F401
from .test_kit_edits_kept import MOVED_Y_M, _restart, _with_crash
from .test_page import PoseSender

FLAG = "#kit-flag"
"""The toolbar's *node's kit changed* button (shown while the editor is closed)."""
NOTICE = "#kit-notice"
SAVED = "document.getElementById('editor-msg').textContent.startsWith('saved')"
"""Page expression: the editor says the node saved."""
DRAWN_MARKERS = """() => { const c = window.batteur.layers.contacts.children;
  return c.length ? c.map(m => m.position.toArray()) : null; }"""
"""Page script: the drawn contact markers' positions (metres), or null while there are none."""


@needs_browser
def test_the_node_kit_changed_notice_shows_with_the_editor_closed(
        crash_in_editor: tuple[Any, GraphicsNodeProcess, Kit]) -> None:  # noqa: F811 - the fixture
    """A user who edited the kit and closed the editor never saw that the node's kit had changed (the notice is in
    the editor): the toolbar now says so, and its button opens the editor on the notice's **load it**."""
    page, node, loaded = crash_in_editor
    _type(page, 0, "0.5")
    page.click("#edit-toggle")  # closed: the edit stays drawn
    assert not page.is_visible(FLAG)  # nothing changed yet
    _restart(page, node, _with_crash(loaded, FINE_X_M, MOVED_Y_M))

    assert not page.is_visible("#editor")
    assert page.is_visible(FLAG) and "the node's kit changed" in page.inner_text(FLAG)
    page.click(FLAG)
    assert page.is_visible("#editor") and page.is_visible(NOTICE)
    assert not page.is_visible(FLAG)  # the editor's own notice says it now
    page.click("#kit-load")
    assert page.evaluate(f"[{CRASH}.position[0], {CRASH}.position[1]]") == [FINE_X_M, MOVED_Y_M]
    page.click("#edit-toggle")
    assert not page.is_visible(FLAG) and not page.is_visible(NOTICE)


@needs_browser
def test_mirror_gives_the_kit_models_left_handed_kit(
        crash_in_editor: tuple[Any, GraphicsNodeProcess, Kit]) -> None:  # noqa: F811 - the fixture
    """There was no mirror in the editor: **mirror** now turns the edited kit into ``Kit.mirrored`` of it (x
    mirrored, pitch and yaw negated, hands and feet swapped, hit points and pair preferences mirrored), shown at
    once, and the saved file loads as exactly that kit."""
    page, node, loaded = crash_in_editor
    page.click("#kit-mirror")
    rows = page.eval_on_selector_all("#kit-sliders .slider", ROW_VALUES)
    assert rows[0][1:] == [str(-FINE_X_M), str(-FINE_X_M)] and rows[5][1:] == [str(-FINE_YAW_DEG)] * 2
    drawn = page.evaluate("window.batteur.layers.kit.children.filter(g => g.isGroup).map(g => g.position.x)")
    assert -FINE_X_M in drawn and FINE_X_M not in drawn  # the crash is drawn where it now stands
    assert _save(page, node, "left.yaml") == loaded.mirrored()


def _markers_after_strike(page: Any, node: GraphicsNodeProcess, sender: PoseSender, r: float,
                          theta: float) -> list[list[float]]:
    """Strike the crash at (``r``, ``theta`` radians) until the page draws a contact marker (a node starved of CPU
    may skip the 0.5 s a marker lasts; up to 10 strikes): the markers' positions, metres."""
    from playwright.sync_api import TimeoutError as PlaywrightTimeout

    for seq in range(1, 11):
        node.send(Impact(seq=seq, time=time.monotonic() - sender.t0, instrument="crash", zone="bow", r=r,
                         theta=theta, velocity=3.0, impulse=0.05, peak_force=300.0, duration=0.004,
                         part="right_stick_tip"))
        try:
            return list(page.wait_for_function(DRAWN_MARKERS, timeout=1500).json_value())
        except PlaywrightTimeout:
            continue
    raise AssertionError("no contact marker drawn after 10 strikes")


@needs_browser
@pytest.mark.parametrize("editor_open", [False, True])
def test_contact_markers_are_drawn_on_the_edited_kit(
        crash_in_editor: tuple[Any, GraphicsNodeProcess, Kit], editor_open: bool) -> None:  # noqa: F811
    """With the crash moved and turned in the editor (not saved), a strike's marker floated where the crash stood
    in the saved kit: it is now on the crash as drawn, at the struck point of its surface, the editor closed or
    open (its frames carried no markers)."""
    page, node, loaded = crash_in_editor
    _type(page, 0, "0.5")
    _type(page, 5, "60")  # yaw: the struck point turns with the cymbal
    if not editor_open:
        page.click("#edit-toggle")
    edited = loaded.model_dump(mode="json")
    crash = next(o for o in edited["objects"] if o["id"] == "crash")
    crash["position"][0], crash["rotation_deg"][2] = 0.5, 60.0
    r, theta = 0.8, 0.3
    expected = impact_point(Kit.model_validate(edited).object("crash"), r, theta)
    saved_kit = impact_point(loaded.object("crash"), r, theta)
    assert np.linalg.norm(expected - saved_kit) > 0.2  # the test tells the two apart

    sender = PoseSender(node, SyntheticDrummer(strokes={}, duration=0.0).pose(0.0))
    try:
        page.wait_for_function("window.batteur.frames > 5", timeout=15000)
        markers = _markers_after_strike(page, node, sender, r, theta)
    finally:
        sender.stop()
    assert page.is_visible("#editor") == editor_open
    for marker in markers:  # the node rounds a marker to 1 mm
        assert marker == pytest.approx(expected.tolist(), abs=2e-3), (marker, expected, saved_kit)


@needs_browser
def test_enter_in_the_pose_name_field_saves_the_pose(
        crash_in_editor: tuple[Any, GraphicsNodeProcess, Kit]) -> None:  # noqa: F811 - the fixture
    """Enter in the pose-name field did nothing (it saves in the kit's file-name field): it saves the pose, as the
    **save pose** button does."""
    page, node, _ = crash_in_editor
    page.wait_for_function("window.batteur.poser", timeout=10000)
    page.fill("#pose-name", "SNARE.right_hand.DOWN")
    page.press("#pose-name", "Enter")
    page.wait_for_function(SAVED, timeout=10000)
    assert "SNARE.right_hand.DOWN" in KeyPoses.load(node.tmp / "kits" / "poses.yaml").poses


@needs_browser
def test_slider_arrow_keys_step_millimetres_and_degrees(
        crash_in_editor: tuple[Any, GraphicsNodeProcess, Kit]) -> None:  # noqa: F811 - the fixture
    """An arrow key on a slider moved a position by 1 % of the slider's 3 m (3 cm) and an angle by 3.6 degrees:
    it now moves a position 1 mm (Shift: 10 mm) and an angle 1 degree (Shift: 10), from the value as it was,
    on the kit's and the pose's sliders."""
    page, _, loaded = crash_in_editor
    sliders = page.locator("#kit-sliders input[type=range]")
    sliders.nth(0).press("ArrowRight")
    assert page.evaluate(f"{CRASH}.position[0]") == 0.1244
    sliders.nth(0).press("Shift+ArrowRight")
    assert page.evaluate(f"{CRASH}.position[0]") == 0.1344
    sliders.nth(0).press("ArrowDown")
    assert page.evaluate(f"{CRASH}.position[0]") == 0.1334
    assert page.eval_on_selector_all("#kit-sliders .slider", ROW_VALUES)[0][1:] == ["0.1334", "0.1334"]
    sliders.nth(5).press("ArrowLeft")
    assert page.evaluate(f"{CRASH}.rotation_deg[2]") == FINE_YAW_DEG - 1
    sliders.nth(5).press("Shift+ArrowUp")
    assert page.evaluate(f"{CRASH}.rotation_deg[2]") == FINE_YAW_DEG + 9
    sliders.nth(6).press("ArrowUp")  # radius, metres
    assert page.evaluate(f"{CRASH}.radius") == round(loaded.object("crash").radius + 0.001, 9)

    page.wait_for_function("window.batteur.poser", timeout=10000)
    page.select_option("#pose-joint", "left_elbow")
    before = page.evaluate("window.batteur.poser.angles.left_elbow[0]")
    pose = page.locator("#pose-sliders input[type=range]").first
    pose.press("ArrowRight")
    assert page.evaluate("window.batteur.poser.angles.left_elbow[0]") == pytest.approx(before + 1, abs=1e-9)
    pose.press("Shift+ArrowLeft")
    assert page.evaluate("window.batteur.poser.angles.left_elbow[0]") == pytest.approx(before - 9, abs=1e-9)
