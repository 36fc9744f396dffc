"""The live view in a real browser (Debian's chromium, headless, driven by Playwright).

One browser session: the page loads from the graphics node, receives poses
sent over OSC, draws the drummer and the kit where the camera must see them
(pixels checked against a projection computed here), follows a moved pose,
and reconnects by itself after the node restarts. Then the pose editor on
physics' 57-DOF body, and the Pure Data panel and the kit editor changing what
the page draws.
"""

from __future__ import annotations

import math
import socket
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from common.character import JOINTS
from common.kit import load_kit
from common.messages import Impact, Pose, Skeleton
from common.messages.physics import PhysicsPosture, PhysicsReset
from services.graphics.figure import LINK_NAMES, SyntheticDrummer
from services.graphics.poser import load_character
from tests.deploy.pdrun import PD_DIR, PdProcess, pd_binary

from .conftest import GraphicsNodeProcess, needs_browser, open_page, project, received_from

WIDTH, HEIGHT = 800, 450
# the page's "front" preset: azimuth 0, elevation 18 degrees, 3 m from (0, 0.35, 0.75), 45 degree fov
TARGET = np.array([0.0, 0.35, 0.75])
EYE = TARGET + 3.0 * np.array([0.0, math.cos(math.radians(18)), math.sin(math.radians(18))])
# the "side" preset: azimuth 90, elevation 12 degrees, 3 m from the same target
SIDE_EYE = TARGET + 3.0 * np.array([math.cos(math.radians(12)), 0.0, math.sin(math.radians(12))])
BACKGROUND = np.array([0x1B, 0x1D, 0x22])
SET_SLIDER = "(el, v) => { el.value = v; el.dispatchEvent(new Event('input')); }"
"""Page script: move a range input (el) to v as a user would (an input event)."""
SLIDER_LABELS = "rows => rows.map(r => r.firstChild.textContent)"
"""Page script: the labels of the editor's slider rows."""


class PoseSender:
    """Sends the skeleton once a second and a still pose at 30 Hz (shifted by ``dx`` metres) until stopped."""

    def __init__(self, node: GraphicsNodeProcess, pose: np.ndarray, names: list[str] | None = None) -> None:
        self.node, self.pose, self.dx = node, pose, 0.0
        self.names = tuple(names or LINK_NAMES)
        self.t0 = time.monotonic()
        self._stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        n = 0
        while not self._stop.is_set():
            if n % 30 == 0:
                self.node.send(Skeleton(layout=3, names=self.names))
            values = self.pose.copy()
            values[:, 0] += self.dx
            try:
                self.node.send(Pose(time=time.monotonic() - self.t0, layout=3, values=tuple(values.ravel())))
            except OSError:
                pass
            n += 1
            time.sleep(1 / 30)

    def stop(self) -> None:
        self._stop.set()
        self.thread.join(2)


READ_PATCHES = """(spots) => {
  const src = document.getElementById('view');
  const c = document.createElement('canvas');
  c.width = src.width; c.height = src.height;
  const ctx = c.getContext('2d');
  ctx.drawImage(src, 0, 0);
  return spots.map(([x, y, h]) => Array.from(ctx.getImageData(x - h, y - h, 2 * h + 1, 2 * h + 1).data));
}"""


def _patches(page: object, spots: list[tuple[float, float]], half: int = 3) -> list[np.ndarray]:
    """RGB pixels (n, 3) around each spot of the rendered 3D canvas (the WebGL buffer, not the HTML panels)."""
    spots_int = [[int(round(x)), int(round(y)), half] for x, y in spots]
    data = page.evaluate(READ_PATCHES, spots_int)  # type: ignore[attr-defined]
    return [np.asarray(d, dtype=float).reshape(-1, 4)[:, :3] for d in data]


def _wait_for(page: object, spots: list[tuple[float, float]], check: object, timeout: float = 8.0) -> list[np.ndarray]:
    """Read the patches until ``check(patches)`` holds (the machine may be busy); the last patches either way."""
    deadline = time.monotonic() + timeout
    while True:
        patches = _patches(page, spots)
        if check(patches) or time.monotonic() > deadline:  # type: ignore[operator]
            return patches
        time.sleep(0.1)


def _open_page(url: str, frames: int) -> Any:
    """The page once it has drawn ``frames`` frames, WIDTH x HEIGHT: (page, page errors so far)."""
    return open_page(url, frames, WIDTH, HEIGHT)


def _is_body_blue(patch: np.ndarray) -> bool:
    """The body material is blue (0x4f86c6, lit): blue clearly above red in most pixels."""
    return float(np.mean(patch[:, 2] - patch[:, 0] > 40)) > 0.6


def _is_drum_red(patch: np.ndarray) -> bool:
    """The drum shells are red: red clearly above green and blue in most pixels (not the wooden pedal)."""
    return float(np.mean((patch[:, 0] - patch[:, 1] > 50) & (patch[:, 0] - patch[:, 2] > 50))) > 0.6


@needs_browser
def test_page_draws_drummer_and_reconnects(graphics_node: GraphicsNodeProcess) -> None:
    from playwright.sync_api import TimeoutError as PlaywrightTimeout

    drummer = SyntheticDrummer(strokes={}, duration=0.0)
    rest = drummer.pose(0.0)
    head = rest[LINK_NAMES.index("head"), :3] + np.array([0.0, 0.0, 0.09])  # the page draws the head there
    kick = np.asarray(drummer.kit.object("kick").position)
    sender = PoseSender(graphics_node, rest)
    try:
        with _open_page(graphics_node.url, 20) as (page, errors):
            head_px = project(head, EYE, TARGET, 45, WIDTH, HEIGHT)
            kick_px = project(kick, EYE, TARGET, 45, WIDTH, HEIGHT)
            head_patch, kick_patch, sky = _wait_for(page, [head_px, kick_px, (WIDTH * 0.5, 12)],
                                                    lambda p: _is_body_blue(p[0]))
            page.screenshot(path=str(graphics_node.tmp / "page.png"))  # kept for a person to look at
            assert _is_body_blue(head_patch), f"no body at the head's pixel {head_px}"
            assert np.mean(kick_patch[:, 0] - kick_patch[:, 2] > 40) > 0.6, f"no red kick drum at {kick_px}"
            assert np.abs(sky - BACKGROUND).max() < 12, "the sky above the drummer should be background"

            # move the drummer 0.6 m to its right: the head must follow, the old place must be empty
            sender.dx = 0.6
            new_px = project(head + np.array([0.6, 0.0, 0.0]), EYE, TARGET, 45, WIDTH, HEIGHT)
            moved, old = _wait_for(page, [new_px, head_px], lambda p: _is_body_blue(p[0]) and not _is_body_blue(p[1]))
            assert _is_body_blue(moved), f"no body at the moved head's pixel {new_px}"
            assert not _is_body_blue(old), "the head is still drawn where it was"
            sender.dx = 0.0

            # impacts sent over OSC reach the page: the struck snare's flash value rises. The flash is above 0.5
            # for 83 ms of display time, which a node starved of CPU can skip between two frames: strike again
            # (up to 10 times) rather than fail on the machine's load
            assert page.evaluate("window.batteur.peakFlash") == 0
            for seq in range(1, 11):
                graphics_node.send(Impact(seq=seq, time=time.monotonic() - sender.t0, instrument="snare",
                                          zone="centre", r=0.3, theta=0.0, velocity=4.0, impulse=0.05,
                                          peak_force=400.0, duration=0.004, part="left_stick_tip"))
                try:
                    page.wait_for_function("window.batteur.peakFlash > 0.5", timeout=1000)
                    break
                except PlaywrightTimeout:
                    continue
            assert page.evaluate("window.batteur.peakFlash") > 0.5, "no snare flash after 10 strikes"
            assert errors == []

            # restart the node: the page must reconnect by itself and show frames again
            graphics_node.stop()
            page.wait_for_function("window.batteur.connected === false", timeout=10000)
            graphics_node.start()
            page.wait_for_function("window.batteur.connects >= 2 && window.batteur.connected", timeout=15000)
            frames = page.evaluate("window.batteur.frames")
            page.wait_for_function(f"window.batteur.frames > {frames + 10}", timeout=10000)
            assert errors == []
    finally:
        sender.stop()


@needs_browser
def test_pose_editor_poses_the_57_dof_body_and_drives_physics(tmp_path: Path) -> None:
    """Editor open: sliders are physics' DOF; moving one bends the drawn body and sends physics the posture."""
    physics = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)  # stands in for the physics node
    physics.bind(("127.0.0.1", 0))
    physics.settimeout(0.2)
    node = GraphicsNodeProcess(tmp_path, extra=["--peer", f"physics=127.0.0.1:{physics.getsockname()[1]}"])
    node.start()
    body = load_character()
    sender = PoseSender(node, body.rest, names=body.names)  # physics' drummer at rest, streamed live

    try:
        with _open_page(node.url, 10) as (page, errors):
            page.click("#edit-toggle")
            page.wait_for_function("window.batteur.poser && window.batteur.poser.joints", timeout=10000)
            poser = page.evaluate("window.batteur.poser")
            assert poser["body"] == "live" and poser["joints"] == list(JOINTS)
            page.select_option("#pose-joint", "right_elbow")
            labels = page.eval_on_selector_all("#pose-sliders .slider", SLIDER_LABELS)
            assert labels == ["right_elbow_x", "right_elbow_y", "right_elbow_z"]
            lo, hi = (float(page.get_attribute("#pose-sliders input", k) or "nan") for k in ("min", "max"))
            assert lo == pytest.approx(math.degrees(body.lower[JOINTS.index("right_elbow") * 3]), abs=0.1) and hi > lo
            hand = body.names.index("right_hand")
            before = np.array(page.evaluate(f"window.batteur.lastFrame.p.slice({hand * 7}, {hand * 7 + 3})"))
            start = poser["angles"]["right_elbow"][0]
            page.eval_on_selector("#pose-sliders input", SET_SLIDER, str(start + 30))
            postures = received_from(physics, PhysicsPosture)
            assert postures, "no /batteur/physics/posture reached physics"
            q = np.array(postures[-1].values)
            elbow = JOINTS.index("right_elbow") * 3
            assert math.degrees(q[elbow]) == pytest.approx(start + 30, abs=0.3)
            page.wait_for_function(
                f"Math.hypot(...window.batteur.lastFrame.p.slice({hand * 7}, {hand * 7 + 3})"
                f".map((v, i) => v - {before.tolist()}[i])) > 0.05", timeout=10000)  # the drawn hand moved
            page.screenshot(path=str(tmp_path / "editor.png"))
            page.click("#edit-toggle")  # closing the editor releases the body
            assert received_from(physics, PhysicsReset), "closing the editor sent no /batteur/physics/reset"
            assert errors == []
    finally:
        sender.stop()
        node.close()
        physics.close()


@needs_browser
@pytest.mark.skipif(pd_binary() is None, reason="needs Pure Data (Debian: apt-get install puredata-core)")
def test_pd_panel_and_kit_editor_change_what_the_page_draws(graphics_node: GraphicsNodeProcess) -> None:
    """The Pd panel's GRAPHICS controls reach the page through the node (layers, trails, plot, camera), and the
    kit editor's sliders move a drum in the picture and save the kit file every service loads."""
    drummer = SyntheticDrummer(strokes={}, duration=0.0)
    rest = drummer.pose(0.0)
    head = rest[LINK_NAMES.index("head"), :3] + np.array([0.0, 0.0, 0.09])
    kick = np.asarray(drummer.kit.object("kick").position)
    moved_kick = kick + np.array([-0.65, 0.0, 0.0])  # to the drummer's left, where nothing red stands
    sender = PoseSender(graphics_node, rest)

    def panel(*sends: str, until: str, page: Any) -> None:
        """Run pd/control.pd headless with these -send messages until the page's state satisfies ``until``."""
        pd = PdProcess(PD_DIR / "control.pd", sends=[f"bp-port-graphics {graphics_node.osc_port}", *sends])
        try:
            page.wait_for_function(until, timeout=15000)
        finally:
            pd.stop()
        assert pd.errors() == [], "\n".join(pd.lines)

    try:
        with _open_page(graphics_node.url, 20) as (page, errors):
            kick_px, moved_px = (project(p, EYE, TARGET, 45, WIDTH, HEIGHT) for p in (kick, moved_kick))
            (old,) = _wait_for(page, [kick_px], lambda p: _is_drum_red(p[0]))
            assert _is_drum_red(old), f"no red kick drum at {kick_px}"

            # kit editor: the kick's "pos x" slider moves the drawn drum; "save kit" writes a kit every service loads
            page.click("#edit-toggle")
            page.select_option("#kit-object", "kick")
            labels = page.eval_on_selector_all("#kit-sliders .slider", SLIDER_LABELS)
            assert labels == ["pos x", "pos y", "pos z", "roll", "pitch", "yaw", "radius"]
            page.eval_on_selector("#kit-sliders input", SET_SLIDER, str(round(float(moved_kick[0]), 3)))
            new, old = _wait_for(page, [moved_px, kick_px], lambda p: _is_drum_red(p[0]) and not _is_drum_red(p[1]))
            assert _is_drum_red(new), f"the moved kick is not drawn at {moved_px}"
            assert not _is_drum_red(old), f"the kick is still drawn at {kick_px}"
            page.fill("#kit-file", "moved-kick.yaml")
            page.click("#kit-save")
            saved = graphics_node.tmp / "kits" / "moved-kick.yaml"
            deadline = time.monotonic() + 10
            while not saved.is_file() and time.monotonic() < deadline:
                time.sleep(0.1)
            assert load_kit(saved).object("kick").position == pytest.approx(tuple(moved_kick), abs=1e-3)
            page.click("#edit-toggle")

            # the Pd panel: hide the kit, trails off, plot hidden and a 2 s window
            panel("bp-show-kit 0", "bp-trails 0", "bp-plot-window 2", "bp-show-plot 0",
                  until="window.batteur.view && window.batteur.view.layers.kit === false && "
                  "window.batteur.view.layers.plot === false && window.batteur.view.trails === 0 && "
                  "Math.abs(window.batteur.view.plot.window - 2) < 1e-3", page=page)
            (hidden,) = _wait_for(page, [moved_px], lambda p: not _is_drum_red(p[0]))
            assert not _is_drum_red(hidden), "the kit is still drawn after bp-show-kit 0"
            assert page.eval_on_selector("#plot", "el => el.classList.contains('hidden')")
            trail_points = page.evaluate("Math.max(...[...window.batteur.trails.values()].map(t => t.points.length))")
            assert trail_points <= 1  # no trail behind the tips (the newest point only)

            # kit back on, side camera: the head is where the side view must show it
            side_head = project(head, SIDE_EYE, TARGET, 45, WIDTH, HEIGHT)
            panel("bp-show-kit 1", "bp-show-plot 1", "bp-camera symbol side",
                  until="window.batteur.view.camera.preset === 'side' && window.batteur.view.layers.kit === true",
                  page=page)
            (seen,) = _wait_for(page, [side_head], lambda p: _is_body_blue(p[0]))
            assert _is_body_blue(seen), f"no body at the head's pixel {side_head} in the side view"
            assert not page.eval_on_selector("#plot", "el => el.classList.contains('hidden')")
            page.screenshot(path=str(graphics_node.tmp / "side.png"))
            assert errors == []
    finally:
        sender.stop()
