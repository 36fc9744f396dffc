"""What the viewer shows a user, each against the defect it was written for: the drummer's-eye camera, the
editor beside the plot in a short window, joint angles off the old 0.5 degree slider grid, and a view with
nothing to draw (no physics, the preview mode without a preview) saying so.
"""

from __future__ import annotations

import json
import math
import socket
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from common.character import JOINTS
from common.kit import load_kit
from common.messages.graphics import GraphicsCamera, GraphicsMode
from common.messages.physics import PhysicsPosture
from services.graphics.camera import PRESETS
from services.graphics.poser import SNAPSHOT, load_character
from services.physics.anthropometry import anthropometry

from .conftest import GraphicsNodeProcess, needs_browser, open_page, project, received_from
from .test_page import PoseSender, _wait_for

PANELS = "ids => ids.map(id => { const r = document.getElementById(id).getBoundingClientRect(); " \
         "return [r.left, r.top, r.right, r.bottom]; })"
"""Page script: the bounding boxes (left, top, right, bottom; CSS pixels) of the elements with these ids."""
SET_SLIDER = "(el, v) => { el.value = v; el.dispatchEvent(new Event('input')); }"
"""Page script: move a range input (el) to v as a user would (an input event)."""


def _overlap(a: list[float], b: list[float]) -> bool:
    """Whether two boxes (left, top, right, bottom) share any area."""
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


# --- the drummer preset looks from the drummer's eyes ------------------------------------------------------------
def _head_at_rest() -> tuple[np.ndarray, Rotation, float]:
    """Physics' drummer's head at rest (character.json): the centre of its sphere (metres), its rotation and
    its radius (metres), as services/physics/character.py builds it."""
    body = load_character()
    head = body.rest[body.names.index("head")]
    turn = Rotation.from_quat(head[3:])
    a = anthropometry(json.loads(SNAPSHOT.read_text(encoding="utf-8"))["height_m"])
    centre = head[:3] + turn.apply([0.0, 0.02 * a.scale, a.segments["head"].com_from_proximal_m])
    return centre, turn, 0.1 * a.scale


def test_the_drummer_preset_looks_from_the_drummers_eyes() -> None:
    """The preset sat 0.5 m behind and above the head (the head filled the picture): its eye is now in the
    front of physics' drummer's head at rest, and it looks forward, down at the kit."""
    drummer = PRESETS["drummer"]
    assert drummer.eye is not None
    centre, turn, radius = _head_at_rest()
    offset = turn.inv().apply(np.array(drummer.eye) - centre)  # in the head's frame: +y is where the face looks
    assert np.linalg.norm(offset) < radius, f"the eye {drummer.eye} is outside the head (offset {offset})"
    assert offset[1] > 0.5 * radius, f"the eye {drummer.eye} is not in the front of the head (offset {offset})"
    gaze = np.array(drummer.target) - np.array(drummer.eye)
    assert gaze[1] > 0 and gaze[2] < 0, "from the eyes the camera must look forward and down at the kit"


@needs_browser
def test_the_drummer_preset_shows_the_kit_not_the_drummers_head(tmp_path: Path) -> None:
    """Physics' drummer at rest streamed to the page, drummer preset: the snare (straight ahead and down) is
    drawn where the preset's projection puts it, not hidden behind the drummer's own head."""
    node = GraphicsNodeProcess(tmp_path)
    node.start()
    body = load_character()
    sender = PoseSender(node, body.rest, names=body.names)
    width, height = 800, 450
    drummer = PRESETS["drummer"]
    assert drummer.eye is not None
    snare = np.asarray(load_kit("default").object("snare").position)
    try:
        with open_page(node.url, 10, width, height) as (page, errors):
            node.send(GraphicsCamera(preset="drummer", azimuth_deg=0.0, elevation_deg=0.0, distance=1.0,
                                     target_x=0.0, target_y=0.0, target_z=0.0))
            page.wait_for_function("window.batteur.view.camera.preset === 'drummer'", timeout=10000)
            px = project(snare, np.array(drummer.eye), np.array(drummer.target), 45, width, height)
            assert 0 < px[0] < width and 0 < px[1] < height, f"the snare is out of the picture ({px})"

            def snare_head(patches: list[np.ndarray]) -> bool:  # the light membrane (0xe8e4d8, lit), not body blue
                patch = patches[0]
                return float(np.mean((patch.min(axis=1) > 120) & (patch[:, 2] - patch[:, 0] < 20))) > 0.6

            (patch,) = _wait_for(page, [px], snare_head)
            page.screenshot(path=str(tmp_path / "drummer-preset.png"))
            assert snare_head([patch]), f"no snare head at {px}: {patch.mean(axis=0)}"
            assert errors == []
    finally:
        sender.stop()
        node.close()


# --- the editor never covers the plot ----------------------------------------------------------------------------
@needs_browser
@pytest.mark.parametrize(("width", "height"), [(1280, 560), (1000, 700), (800, 450), (800, 360), (600, 800)])
def test_the_open_editor_never_covers_the_plot(synthetic_node: GraphicsNodeProcess, width: int, height: int) -> None:
    """In windows under about 900 px tall the open editor ran down over the tip-height plot. It now ends above
    the plot (and scrolls), or, with too little room there, the plot moves left of it; nothing covers the
    status panel or the toolbar, and the editor keeps a usable height."""
    with open_page(synthetic_node.url, 10, width, height, wait_for_status=True) as (page, errors):
        page.click("#edit-toggle")
        page.wait_for_function("window.batteur.poser && window.batteur.poser.joints", timeout=10000)
        page.wait_for_function("document.querySelectorAll('#pose-sliders .slider').length === 3", timeout=10000)
        status, toolbar, editor, plot = page.evaluate(PANELS, ["status", "toolbar", "editor", "plot"])
        page.screenshot(path=str(synthetic_node.tmp / f"editor-{width}x{height}.png"))
        assert not _overlap(editor, plot), f"editor {editor} covers the plot {plot}"
        for name, box in (("status", status), ("toolbar", toolbar)):
            assert not _overlap(editor, box), f"editor {editor} covers the {name} {box}"
            assert not _overlap(plot, box), f"plot {plot} covers the {name} {box}"
        assert editor[3] - editor[1] >= 150, f"the editor is too short to use: {editor}"
        assert editor[3] <= height and plot[3] <= height and min(editor[0], plot[0]) >= 0, "a panel is cut off"
        # closing the editor puts the plot back in its corner
        page.click("#edit-toggle")
        (plot,) = page.evaluate(PANELS, ["plot"])
        assert plot[2] == pytest.approx(width - 8, abs=1.5)
        assert errors == []


# --- joint angles between the old slider grid points ------------------------------------------------------------
@pytest.fixture
def editing_physics(tmp_path: Path) -> Iterator[tuple[Any, socket.socket]]:
    """The editor open on physics' drummer (streamed live, at rest) with the right elbow picked: (page, the
    socket standing in for physics)."""
    physics = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    physics.bind(("127.0.0.1", 0))
    physics.settimeout(0.2)
    node = GraphicsNodeProcess(tmp_path, extra=["--peer", f"physics=127.0.0.1:{physics.getsockname()[1]}"])
    node.start()
    body = load_character()
    sender = PoseSender(node, body.rest, names=body.names)
    try:
        with open_page(node.url, 10, 1000, 700) as (page, errors):
            page.click("#edit-toggle")
            page.wait_for_function("window.batteur.poser && window.batteur.poser.body === 'live'", timeout=10000)
            page.select_option("#pose-joint", "right_elbow")
            yield page, physics
            assert errors == []
    finally:
        sender.stop()
        node.close()
        physics.close()


ELBOW = JOINTS.index("right_elbow") * 3
"""The right elbow's x DOF in physics' posture (57 angles, radians)."""


def _elbow_sent(physics: socket.socket) -> float:
    """The right elbow's x angle (degrees) of the newest posture reaching physics."""
    postures = received_from(physics, PhysicsPosture)
    assert postures, "no /batteur/physics/posture reached physics"
    return math.degrees(postures[-1].values[ELBOW])


def _shown(page: Any) -> tuple[float, float]:
    """The right elbow x row: (the slider's value, the number the row shows), degrees."""
    return (float(page.eval_on_selector("#pose-sliders input[type=range]", "el => el.value")),
            float(page.eval_on_selector("#pose-sliders input[type=number]", "el => el.value")))


@needs_browser
def test_a_typed_joint_angle_is_the_one_physics_gets(editing_physics: tuple[Any, socket.socket]) -> None:
    """The slider moved on a 0.5 degree grid (from its lower limit), so 47.37 degrees could not be set; a number
    field now takes it, and physics gets exactly the angle shown."""
    page, physics = editing_physics
    field = page.locator("#pose-sliders input[type=number]").first
    field.fill("47.37")
    field.press("Enter")
    assert _elbow_sent(physics) == pytest.approx(47.37, abs=1e-4)
    assert _shown(page) == pytest.approx((47.37, 47.37), abs=1e-9)


@needs_browser
def test_a_slider_angle_off_the_old_grid_is_sent_as_shown(editing_physics: tuple[Any, socket.socket]) -> None:
    """Dragged to 31.2345 degrees, the slider used to snap to the grid and show three decimals of it: physics
    now gets the angle the row shows (to 0.01 degree), and the slider stays there."""
    page, physics = editing_physics
    page.eval_on_selector("#pose-sliders input[type=range]", SET_SLIDER, "31.2345")
    assert _elbow_sent(physics) == pytest.approx(31.23, abs=1e-4)  # was 31.0, the nearest point of the 0.5 degree grid
    slider, number = _shown(page)
    assert number == pytest.approx(31.23, abs=1e-9) and slider == pytest.approx(31.23, abs=1e-9)


@needs_browser
def test_an_angle_from_physics_is_shown_where_physics_has_it(editing_physics: tuple[Any, socket.socket]) -> None:
    """The editor starts from the angles physics' body has; the slider snapped them to its grid (up to 0.25
    degree away from the number shown). Every DOF's slider and number now agree with physics' angle."""
    page, _ = editing_physics
    angles = page.evaluate("window.batteur.poser.angles")
    for joint in ("right_elbow", "left_shoulder", "neck"):
        page.select_option("#pose-joint", joint)
        sliders = page.eval_on_selector_all("#pose-sliders input[type=range]", "els => els.map(e => +e.value)")
        numbers = page.eval_on_selector_all("#pose-sliders input[type=number]", "els => els.map(e => +e.value)")
        assert len(sliders) == len(numbers) == 3
        assert sliders == pytest.approx(numbers, abs=1e-9), joint
        assert numbers == pytest.approx(angles[joint], abs=0.005 + 1e-9), joint


# --- nothing to show says so -------------------------------------------------------------------------------------
@needs_browser
def test_the_preview_mode_without_a_preview_says_how_to_load_one(tmp_path: Path) -> None:
    """No physics and no preview: the preview mode asked (Pd panel, batteur send) left an empty kit and no word.
    The page now says there is nothing to show and how to load a preview; it goes when frames come."""
    node = GraphicsNodeProcess(tmp_path, extra=["--clock-master", "self"])
    node.start()
    try:
        with open_page(node.url, -1, 800, 450, wait_for_status=True) as (page, errors):
            node.send(GraphicsMode(mode="preview"))
            page.wait_for_function("window.batteur.view && window.batteur.view.control === 'mode'", timeout=10000)
            notice = page.locator("#notice")
            notice.wait_for(state="visible", timeout=10000)
            text = notice.inner_text()
            assert "no preview" in text and "--preview-score SCORE" in text and "--preview FILE.npz" in text, text
            page.screenshot(path=str(tmp_path / "nothing-to-show.png"))

            body = load_character()  # poses arrive (physics started): the notice goes
            sender = PoseSender(node, body.rest, names=body.names)
            try:
                notice.wait_for(state="hidden", timeout=10000)
            finally:
                sender.stop()
            assert errors == []
    finally:
        node.close()
