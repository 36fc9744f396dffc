"""The kit's hardware (bass-drum beaters, stand rods) is one set of numbers, common/kit.py's ``kit_hardware``:
physics builds it, the glTF export draws it, and the live view gets it with the kit and draws it. The page drew
its own beater (a 0.3 m rod, a 2.5 cm ball, 26 cm ahead of the pedal) and its own stands (none under the drums,
8 mm rods up to the object's centre), so the live view, the glTF and physics showed three different kits."""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from websockets.sync.client import connect

from common.kit import Kit, kit_hardware, load_kit
from services.graphics.core import GraphicsCore, GraphicsSettings
from services.graphics.server import ViewServer

from . import test_kit_editor
from .conftest import GraphicsNodeProcess, needs_browser, open_page
from .test_kit_editor import _type

KITS = ["default", "double_pedal"]
crash_in_editor = test_kit_editor.crash_in_editor
"""The kit editor's fixture: a node drawing the fine kit, the page with the editor open on the crash."""


def _numbers(kit: Kit) -> dict[str, Any]:
    """``kit_hardware(kit)`` as the page gets it (JSON)."""
    return json.loads(kit_hardware(kit).model_dump_json())


@pytest.mark.parametrize("name", KITS)
def test_kit_hardware_is_what_physics_builds_and_the_gltf_draws(name: str) -> None:
    """Each beater's axle and rest angle are physics' beater link's, its rod and ball physics' shapes; the stand
    rods are physics' stand shapes (the glTF export draws these numbers: tests/graphics/test_export.py)."""
    import pybullet

    from services.physics import kitbodies
    from services.physics.world import World

    kit = load_kit(name)
    hardware = kit_hardware(kit)
    world = World()
    try:
        kb = kitbodies.build_kit(world, kit)
        frames = {link: world.link_frame(body, index) for link, body, index in kb.pose_links}
        stands = world.client.getVisualShapeData(next(body for link, body, _ in kb.pose_links
                                                      if link == "kit.stands"))
        shapes = {link: [(s[2], s[3], s[5]) for s in world.client.getVisualShapeData(body) if s[1] == index]
                  for link, body, index in kb.pose_links if link.endswith(".beater")}
    finally:
        world.close()
    assert [b.pedal for b in hardware.beaters] == (["kick_pedal", "kick_pedal_left"] if kit.double_pedal
                                                   else ["kick_pedal"])
    for beater in hardware.beaters:
        position, quat = frames[f"kit.{beater.pedal}.beater"]
        assert np.allclose(position, beater.axle, atol=1e-9)  # metres
        at_rest = Rotation.from_rotvec([beater.rest_rad - beater.lean_rad, 0.0, 0.0])
        assert (Rotation.from_quat(quat) * at_rest.inv()).magnitude() < 1e-6  # radians
        assert np.allclose(np.add(kit.object(beater.pedal).position, beater.axle_from_pedal), beater.axle)
        rod, ball = shapes[f"kit.{beater.pedal}.beater"]  # physics' visual shapes: (kind, size, offset)
        assert (rod[0], ball[0]) == (pybullet.GEOM_CYLINDER, pybullet.GEOM_SPHERE)
        assert rod[1][:2] == pytest.approx((beater.rod_length, beater.rod_radius), abs=1e-6)  # (length, radius)
        assert ball[1][0] == pytest.approx(beater.ball_radius)
        # offsets are from the link's centre of mass: the rod is centred half way to the ball
        assert ball[2][2] - rod[2][2] == pytest.approx(beater.rod_length / 2, abs=1e-6)
    # physics' stand rods: cylinders centred half way up under each top
    built = sorted((s[5][0], s[5][1], s[5][2], s[3][0], s[3][1]) for s in stands)  # (length, radius)
    ours = sorted((r.top[0], r.top[1], r.height / 2, r.height, r.radius) for r in hardware.stands)
    assert len(ours) == len(built) >= 10 and np.allclose(ours, built, atol=1e-6)


def test_the_kit_message_carries_the_hardware() -> None:
    """What a page gets on connecting and when the kit changes: the kit and its hardware numbers."""
    core = GraphicsCore(GraphicsSettings(latency=0.0, clock="rig"), kit=load_kit("double_pedal"))
    message = json.loads(json.dumps(core.welcome()[0]))
    assert message["type"] == "kit" and message["hardware"] == _numbers(load_kit("double_pedal"))
    core.set_kit(load_kit("default"))
    sent = [m for m in core.take_page_messages() if m["type"] == "kit"]
    assert json.loads(json.dumps(sent[-1]))["hardware"] == _numbers(load_kit("default"))


def _moved_crash(kit: Kit, x: float) -> dict[str, Any]:
    """``kit`` (JSON) with the crash moved to ``x`` metres."""
    data = kit.model_dump(mode="json")
    next(o for o in data["objects"] if o["id"] == "crash")["position"][0] = x
    return data


def test_a_page_gets_the_hardware_of_the_kit_it_edits() -> None:
    """The page's edited kit (not saved) is the node's to compute: a ``hardware`` request answers with
    ``kit_hardware`` of that kit; a kit that is not valid gets an error reply, counted, and changes nothing."""
    server = ViewServer(GraphicsCore(GraphicsSettings(latency=0.0, clock="rig")))
    edited = _moved_crash(load_kit(), 0.5)
    reply = server.handle_page_message(json.dumps({"type": "hardware", "kit": edited}))
    assert reply is not None and reply["type"] == "hardware"
    assert json.loads(json.dumps(reply["hardware"])) == _numbers(Kit.model_validate(edited))
    assert reply["hardware"] != _numbers(load_kit())  # the crash's stand moved
    broken = {**edited, "objects": "none"}
    reply = server.handle_page_message(json.dumps({"type": "hardware", "kit": broken}))
    assert reply is not None and reply["type"] == "hardware" and "hardware" not in reply and reply["error"]
    assert server.counters["page_errors"] == 1
    assert server.core.kit == load_kit()


def test_the_page_socket_delivers_the_hardware(graphics_node: GraphicsNodeProcess) -> None:
    """Over the node's WebSocket, as the page reads it: the first message is the kit with its hardware."""
    with connect(f"ws://127.0.0.1:{graphics_node.http_port}/ws", open_timeout=10) as ws:
        first = json.loads(ws.recv(timeout=10))
    assert first["type"] == "kit" and first["hardware"] == _numbers(load_kit("default"))


# --- the page ----------------------------------------------------------------------------------------------------
DRAWN = """() => { const h = window.batteur.hardware; const world = (o) => { o.updateWorldMatrix(true, false);
  return new o.position.constructor().setFromMatrixPosition(o.matrixWorld).toArray(); };
  const k = window.batteur.lastFrame?.k ?? [];
  return {
    beaters: h.beaters.map(b => ({ pedal: b.pedal, axle: world(b.group), rod: b.rod.geometry.parameters.height,
      rodRadius: b.rod.geometry.parameters.radiusTop, ball: world(b.ball),
      ballRadius: b.ball.geometry.parameters.radius,
      angle: b.group.rotation.x, press: k.length ? k[b.index * 4 + 3] : 0 })),
    stands: h.stands.map(m => ({ centre: world(m), height: m.geometry.parameters.height,
      radius: m.geometry.parameters.radiusTop })) }; }"""
"""Page script: the drawn beaters (axle, rod, ball in world metres, the angle and the press of the frame drawn) and
stand rods (centre, height, radius), read from the page's three.js scene."""


def _drawn_matches(drawn: dict[str, Any], kit: Kit) -> None:
    """The page's beaters and stand rods are ``kit_hardware(kit)``'s, the beaters at the drawn frame's press."""
    hardware = kit_hardware(kit)
    assert [b["pedal"] for b in drawn["beaters"]] == [b.pedal for b in hardware.beaters]
    for page_beater, beater in zip(drawn["beaters"], hardware.beaters, strict=True):
        assert np.allclose(page_beater["axle"], beater.axle, atol=1e-6)  # metres
        assert page_beater["rod"] == pytest.approx(beater.rod_length, abs=1e-9)
        assert page_beater["rodRadius"] == pytest.approx(beater.rod_radius, abs=1e-9)
        assert page_beater["ballRadius"] == pytest.approx(beater.ball_radius, abs=1e-9)
        angle = beater.rest_rad * (1.0 - page_beater["press"]) - beater.lean_rad  # geared to the footboard
        assert page_beater["angle"] == pytest.approx(angle, abs=1e-6)
        ball = np.asarray(beater.axle) + beater.rod_length * np.array([0.0, -math.sin(angle), math.cos(angle)])
        assert np.allclose(page_beater["ball"], ball, atol=1e-6)
    drawn_rods = sorted((s["centre"][0], s["centre"][1], s["centre"][2], s["height"], s["radius"])
                        for s in drawn["stands"])
    rods = sorted((r.top[0], r.top[1], r.height / 2, r.height, r.radius) for r in hardware.stands)
    assert len(drawn_rods) == len(rods) and np.allclose(drawn_rods, rods, atol=1e-6)


@pytest.fixture
def double_pedal_node(tmp_path: Path) -> Iterator[GraphicsNodeProcess]:
    """A node playing the synthetic drummer (its feet press the pedals) on the double-pedal kit."""
    node = GraphicsNodeProcess(tmp_path, extra=["--synthetic", "--clock-master", "self", "--kit", "double_pedal"])
    node.start()
    try:
        yield node
    finally:
        node.close()


@needs_browser
def test_the_page_draws_the_beaters_and_stands_physics_builds(double_pedal_node: GraphicsNodeProcess) -> None:
    """Both beaters of the double pedal and every stand rod are where, and as large as, ``kit_hardware`` says,
    the beaters turned as the drawn frame's footboard press gears them; the kick is pressed at some point."""
    with open_page(double_pedal_node.url) as (page, errors):
        presses: list[float] = []
        while len(presses) < 20 or max(presses) <= 0.5:  # the beater checked pressed too, not only at rest
            assert len(presses) < 400, f"the kick pedal was never seen pressed: {max(presses)}"
            drawn = page.evaluate(DRAWN)  # the frame drawn while the synthetic drummer plays
            _drawn_matches(drawn, load_kit("double_pedal"))
            presses.append(drawn["beaters"][0]["press"])
            page.wait_for_timeout(50)
        assert errors == []


@needs_browser
def test_a_moved_crash_takes_its_stand_along(crash_in_editor: tuple[Any, GraphicsNodeProcess, Kit]) -> None:
    """Moving the crash in the kit editor (not saved) moves its stand rod as physics would build it: the page
    asks the node for the edited kit's hardware."""
    page, _, kit = crash_in_editor
    _drawn_matches(page.evaluate(DRAWN), kit)
    _type(page, 0, "0.4321")  # pos x
    edited = Kit.model_validate(_moved_crash(kit, 0.4321))
    before = {r.top for r in kit_hardware(kit).stands}
    (moved,) = [r.top for r in kit_hardware(edited).stands if r.top not in before]  # the crash's
    page.wait_for_function("x => window.batteur.hardware.stands.some(m => Math.abs(m.position.x - x) < 1e-9)",
                           arg=moved[0], timeout=10000)
    _drawn_matches(page.evaluate(DRAWN), edited)
