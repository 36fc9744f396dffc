"""One camera for every view: the browser, `batteur render --video`, the core's numbers and the Pd panel agree.

A user who sets nothing sees the page's "front" preset (azimuth 0, elevation
18 degrees, 3 m from (0, 0.35, 0.75)) everywhere, and the page places every
preset from the table the node sends (services/graphics/camera.py).
"""

from __future__ import annotations

import math
import socket
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from common.messages import decode
from common.messages.graphics import GraphicsCamera
from services.graphics.camera import PRESETS, CameraView, camera_eye, default_camera, presets_json
from services.graphics.core import GraphicsCore, GraphicsSettings
from services.graphics.figure import LINK_NAMES, SyntheticDrummer
from services.graphics.video import TinyRendererScene
from tests.deploy.pdrun import PD_DIR, PdProcess, pd_binary

from .conftest import CHROMIUM, CHROMIUM_FLAGS, GraphicsNodeProcess, needs_browser

FRONT = {"azimuth_deg": 0.0, "elevation_deg": 18.0, "distance": 3.0, "target": (0.0, 0.35, 0.75)}
"""The page's front preset, what the browser has always shown first."""


def test_the_default_camera_is_the_pages_front_preset() -> None:
    front = PRESETS["front"]
    assert (front.azimuth_deg, front.elevation_deg, front.distance, front.target) == tuple(FRONT.values())
    assert default_camera() == {"preset": "front", "azimuth_deg": 0.0, "elevation_deg": 18.0, "distance": 3.0,
                                "target": [0.0, 0.35, 0.75]}


def test_the_core_starts_with_the_default_camera_and_sends_the_presets() -> None:
    view = GraphicsCore(GraphicsSettings(clock="rig")).view_json()
    assert view["camera"] == default_camera()
    assert view["presets"] == presets_json()  # the page places every preset from these numbers
    assert set(view["presets"]) == {"front", "side", "top", "drummer", "orbit"}


def test_the_core_reports_a_named_presets_own_numbers() -> None:
    core = GraphicsCore(GraphicsSettings(clock="rig"))
    side = PRESETS["side"]
    # the Pd panel's preset menu sends the name with whatever numbers its sliders hold
    core.apply_control(GraphicsCamera(preset="side", azimuth_deg=0.0, elevation_deg=18.0, distance=3.0,
                                      target_x=0.0, target_y=0.35, target_z=0.75))
    camera = core.view_json()["camera"]  # was: azimuth 0, where the page draws the side view from 90
    assert (camera["preset"], camera["azimuth_deg"], camera["elevation_deg"], camera["distance"]) == (
        "side", side.azimuth_deg, side.elevation_deg, side.distance)
    core.apply_control(GraphicsCamera(preset="free", azimuth_deg=45.0, elevation_deg=30.0, distance=2.5,
                                      target_x=0.1, target_y=0.2, target_z=0.9))
    assert core.view_json()["camera"] == {"preset": "free", "azimuth_deg": 45.0, "elevation_deg": 30.0,
                                          "distance": 2.5, "target": [0.1, 0.2, 0.9]}  # free: the numbers sent


def test_the_video_frames_the_default_camera() -> None:
    drummer = SyntheticDrummer(strokes={}, duration=0.0)
    scene = TinyRendererScene(list(LINK_NAMES), drummer.pose(0.0), drummer.kit, 64, 36)
    try:
        assert scene.eye.tolist() == pytest.approx(camera_eye(0.0, 18.0, 3.0, (0.0, 0.35, 0.75)), abs=1e-12)
    finally:
        scene.client.disconnect()


@pytest.mark.skipif(pd_binary() is None, reason="needs Pure Data (Debian: apt-get install puredata-core)")
def test_the_pd_panel_starts_from_the_default_camera() -> None:
    """Touching a camera slider (sent as `free` with every value so far) keeps the view where the page had it."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as graphics:
        graphics.bind(("127.0.0.1", 0))
        graphics.settimeout(0.5)
        port = graphics.getsockname()[1]
        pd = PdProcess(PD_DIR / "control.pd", sends=[f"bp-port-graphics {port}", "bp-target-x 0"])
        cams: list[GraphicsCamera] = []
        try:
            deadline = time.monotonic() + 15
            while not cams and time.monotonic() < deadline:
                try:
                    data = graphics.recv(65536)
                except TimeoutError:
                    continue
                cams = [m for m in decode(data).messages if isinstance(m, GraphicsCamera)]
        finally:
            pd.stop()
    assert cams, "\n".join(pd.lines)
    cam = cams[0]
    assert cam.preset == "free"
    assert (cam.azimuth_deg, cam.elevation_deg, cam.distance) == pytest.approx((0.0, 18.0, 3.0), abs=1e-5)
    assert (cam.target_x, cam.target_y, cam.target_z) == pytest.approx((0.0, 0.35, 0.75), abs=1e-5)


# --- the page places each preset from the node's table ----------------------------------------------------------
ODD_SIDE = CameraView(azimuth_deg=45.0, elevation_deg=30.0, distance=2.5, target=(0.1, 0.3, 0.8))
"""A side preset the page cannot know by itself: the node below sends it instead of the shipped one."""
NODE_WITH_ODD_SIDE = (
    "import sys\n"
    "from services.graphics import camera\n"
    f"camera.PRESETS['side'] = camera.CameraView.model_validate({ODD_SIDE.model_dump()!r})\n"
    "from services.graphics.node import main\n"
    "raise SystemExit(main(sys.argv[1:]))\n"
)


class OddSideNode(GraphicsNodeProcess):
    """The graphics node in a subprocess whose side preset is :data:`ODD_SIDE`."""

    def command(self) -> list[str]:
        return [sys.executable, "-c", NODE_WITH_ODD_SIDE, "--no-discovery", "--host", "127.0.0.1",
                "--port", str(self.osc_port), "--http-port", str(self.http_port)]


CAMERA_NOW = "() => [window.batteur.camera.position.toArray(), window.batteur.controls.target.toArray()]"
"""Page script: the three.js camera's position and look-at point, metres."""


def _camera(name: str, az: float = 20.0, el: float = 20.0, dist: float = 2.0,
            target: tuple[float, float, float] = (0.0, 0.0, 1.0)) -> GraphicsCamera:
    return GraphicsCamera(preset=name, azimuth_deg=az, elevation_deg=el, distance=dist, target_x=target[0],
                          target_y=target[1], target_z=target[2])


@needs_browser
def test_the_page_places_each_preset_from_the_nodes_table(tmp_path: Path) -> None:
    from playwright.sync_api import sync_playwright

    node = OddSideNode(tmp_path)
    node.start()
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_FLAGS)
            page = browser.new_page(viewport={"width": 640, "height": 360})
            errors: list[str] = []
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto(node.url)
            page.wait_for_function("window.batteur && window.batteur.view", timeout=20000)

            def placed(message: GraphicsCamera) -> tuple[np.ndarray, np.ndarray]:
                node.send(message)
                # each message names another preset than the one before (a named preset's numbers are the node's)
                page.wait_for_function(f"window.batteur.view.camera.preset === '{message.preset}'", timeout=10000)
                eye, target = page.evaluate(CAMERA_NOW)
                return np.array(eye), np.array(target)

            # what a user who sets nothing sees first: the default camera
            eye, target = (np.array(v) for v in page.evaluate(CAMERA_NOW))
            assert eye == pytest.approx(camera_eye(0.0, 18.0, 3.0, (0.0, 0.35, 0.75)), abs=1e-6)
            assert target == pytest.approx((0.0, 0.35, 0.75), abs=1e-9)
            # a preset's numbers are the node's, whatever the message carries
            eye, target = placed(_camera("side"))
            assert eye == pytest.approx(camera_eye(45.0, 30.0, 2.5, (0.1, 0.3, 0.8)), abs=1e-6)
            assert target == pytest.approx((0.1, 0.3, 0.8), abs=1e-9)
            for name in ("front", "top"):
                view = PRESETS[name]
                eye, target = placed(_camera(name, az=21.0))
                assert eye == pytest.approx(camera_eye(view.azimuth_deg, view.elevation_deg, view.distance,
                                                       view.target), abs=1e-6), name
                assert target == pytest.approx(view.target, abs=1e-9), name
            drummer = PRESETS["drummer"]
            eye, target = placed(_camera("drummer"))
            assert eye == pytest.approx(drummer.eye, abs=1e-6) and target == pytest.approx(drummer.target, abs=1e-9)
            # the orbit turns: its elevation and distance are the preset's
            orbit = PRESETS["orbit"]
            eye, target = placed(_camera("orbit"))
            offset = eye - np.array(orbit.target)
            assert float(np.linalg.norm(offset)) == pytest.approx(orbit.distance, abs=1e-6)
            assert math.degrees(math.asin(offset[2] / orbit.distance)) == pytest.approx(orbit.elevation_deg, abs=1e-4)
            # free: the message's own numbers (float32 on the wire)
            eye, target = placed(_camera("free", az=-30.0, el=25.0, dist=2.2, target=(0.2, 0.1, 0.9)))
            assert eye == pytest.approx(camera_eye(-30.0, 25.0, 2.2, (0.2, 0.1, 0.9)), abs=1e-6)
            assert target == pytest.approx((0.2, 0.1, 0.9), abs=1e-6)
            assert errors == []
            browser.close()
    finally:
        node.close()
