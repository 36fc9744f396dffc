"""The pose editor on physics' 57-DOF body: forward kinematics, the shipped snapshot, driving physics, key poses."""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from common.character import DOF_NAMES, JOINTS, N_DOF
from common.gesture.keyposes import KeyPoses
from common.kit import Limb
from common.messages import decode, encode
from common.messages.physics import PhysicsPosture, PhysicsReset
from services.graphics.core import GraphicsCore, GraphicsSettings
from services.graphics.poser import SNAPSHOT, CharacterPoser, load_character, rest_poser
from services.graphics.server import ViewServer
from services.physics.core import PhysicsCore

from .character_snapshot import build_snapshot


@pytest.fixture(scope="module")
def physics() -> Iterator[PhysicsCore]:
    core = PhysicsCore(scene="drummer")
    try:
        yield core
    finally:
        core.close()


def _same_frames(a: np.ndarray, b: np.ndarray, tol: float = 1e-5) -> None:
    assert np.abs(a[:, :3] - b[:, :3]).max() < tol
    angle = (Rotation.from_quat(a[:, 3:]).inv() * Rotation.from_quat(b[:, 3:])).magnitude()
    assert angle.max() < tol


def _body_pose(core: PhysicsCore) -> np.ndarray:
    return np.asarray(core.pose().values).reshape(-1, 7)


def test_the_shipped_body_is_the_one_physics_builds() -> None:
    """services/graphics/character.json is physics' drummer (else: python -m tests.graphics.character_snapshot)."""
    fresh, shipped = build_snapshot(), json.loads(SNAPSHOT.read_text())
    assert shipped["names"] == fresh["names"]
    assert np.allclose(shipped["limits_deg"], fresh["limits_deg"], atol=1e-3)
    for limb, e in fresh["effectors"].items():
        assert shipped["effectors"][limb]["link"] == e["link"]
        assert np.allclose(shipped["effectors"][limb]["offset"], e["offset"], atol=1e-5)
    # the link offsets (what the forward kinematics uses) agree
    old, new = rest_poser(), CharacterPoser(fresh["names"], np.asarray(fresh["rest"]))
    assert np.allclose(old.offsets, new.offsets, atol=1e-5)


def test_forward_kinematics_matches_physics(physics: PhysicsCore) -> None:
    scene = physics.scene
    body = scene.body  # type: ignore[attr-defined]
    poser = CharacterPoser(physics.names, _body_pose(physics))
    assert poser.angles == pytest.approx(body.state()[0], abs=1e-5)  # angles read back from the link frames
    rng = np.random.default_rng(5)
    try:
        for _ in range(3):
            q = np.clip(body.state()[0] + rng.normal(0, 0.4, N_DOF), body.lower, body.upper)
            body.set_state(q)
            _same_frames(poser.pose(q), _body_pose(physics))
            tips = poser.effectors(poser.pose(q))
            for limb, link in body.tip_links.items():
                assert np.allclose(tips[limb], body.link_pose(link)[0], atol=1e-5)
    finally:
        body.set_state(scene.rest)  # type: ignore[attr-defined]
    # the snapshot body (no physics running) gives the same kinematics
    rest = rest_poser()
    assert rest.names == [n for n in physics.names if not n.startswith("kit.")]
    _same_frames(rest.pose(scene.rest)[: len(rest.names)], _body_pose(physics)[: len(rest.names)])  # type: ignore[attr-defined]


def test_editor_drives_physics_and_saves_key_poses(physics: PhysicsCore, tmp_path: Path) -> None:
    scene = physics.scene
    body = scene.body  # type: ignore[attr-defined]
    physics.handle(PhysicsReset(time=0.0), physics.time, "test")
    graphics = GraphicsCore(GraphicsSettings(latency=0.0))
    server = ViewServer(graphics, kit_dir=tmp_path)
    now = 10.0  # graphics' clock: physics' poses tell it physics' clock (auto)
    graphics.handle(physics.skeleton(), now, "physics")
    graphics.handle(physics.pose(), now, "physics")

    reply = server.handle_page_message(json.dumps({"type": "poser_on"}))
    assert reply is not None and reply["type"] == "poser" and reply["body"] == "live"
    assert reply["joints"] == list(JOINTS)
    assert [d[0] for j in JOINTS for d in reply["dofs"][j]] == list(DOF_NAMES)
    lo, hi = reply["dofs"]["right_elbow"][0][1:]
    assert lo == pytest.approx(math.degrees(body.lower[JOINTS.index("right_elbow") * 3]), abs=0.1) and hi > lo
    q0 = body.state()[0]
    elbow = JOINTS.index("right_elbow") * 3
    assert reply["angles"]["right_elbow"][0] == pytest.approx(math.degrees(q0[elbow]), abs=0.01)

    # a slider moved: the page shows the bent elbow at once, and physics gets the posture
    bent = [reply["angles"]["right_elbow"][0] + 25.0, *reply["angles"]["right_elbow"][1:]]
    before = graphics.frame_at(now)
    server.handle_page_message(json.dumps({"type": "poser", "angles": {"right_elbow": bent}, "drive": True}))
    shown = graphics.frame_at(now)
    assert before is not None and shown is not None
    hand = physics.names.index("right_hand")
    assert np.linalg.norm(shown.pose[hand, :3] - before.pose[hand, :3]) > 0.05
    upper = physics.names.index("right_upper_arm")
    assert shown.pose[upper, :3] == pytest.approx(before.pose[upper, :3], abs=1e-6)
    out = graphics.step(now + 0.01)
    postures = [o for o in out if isinstance(o.message, PhysicsPosture)]
    assert len(postures) == 1 and postures[0].to == "physics"
    message = decode(encode(postures[0].message)).messages[0]  # a valid typed OSC message
    assert isinstance(message, PhysicsPosture) and len(message.values) == N_DOF
    assert message.time == pytest.approx(physics.time, abs=0.02)  # on physics' clock
    assert message.values[elbow] == pytest.approx(q0[elbow] + math.radians(25), abs=1e-4)
    assert not [o for o in graphics.step(now + 0.02) if isinstance(o.message, PhysicsPosture)]  # rate-limited

    # physics glides there and holds it
    t0 = physics.time
    physics.handle(message, t0, "graphics")
    assert not physics.rejected
    for k in range(1, 601):
        physics.step(t0 + k / 1000)
    q = body.state()[0]
    assert q[elbow] - q0[elbow] == pytest.approx(math.radians(25), abs=math.radians(2))

    # the key pose: every joint in degrees, the effectors where the forward kinematics puts them
    saved = server.handle_page_message(json.dumps({"type": "save_pose", "name": "SNARE.right_hand.UP"}))
    assert saved is not None and saved["ok"] is True, saved
    key = KeyPoses.load(tmp_path / "poses.yaml").poses["SNARE.right_hand.UP"]
    assert key.joints["right_elbow"][0] == pytest.approx(bent[0], abs=0.01)
    tip = body.link_pose(body.tip_links["right_hand"])[0]
    assert np.allclose(key.effectors[Limb.RIGHT_HAND], tip, atol=0.03)  # physics reached the edited posture

    bad = server.handle_page_message(json.dumps({"type": "poser", "angles": {"tail": [0, 0, 0]}}))
    assert bad is not None and bad["ok"] is False
    bad = server.handle_page_message(json.dumps({"type": "poser", "angles": {"head": [0, "x", 0]}}))
    assert bad is not None and bad["ok"] is False
    bad = server.handle_page_message(json.dumps({"type": "save_pose", "name": "../x"}))
    assert bad is not None and bad["ok"] is False

    # leaving the editor releases the body (reset) and goes back to the stream
    server.handle_page_message(json.dumps({"type": "poser_off"}))
    out = graphics.step(now + 0.5)
    assert [type(o.message) for o in out if o.to == "physics"] == [PhysicsReset]
    physics.handle(out[-1].message, physics.time, "graphics")
    assert len(scene.joint_track) == 0  # type: ignore[attr-defined]


def test_physics_clamps_an_out_of_range_posture(physics: PhysicsCore) -> None:
    body = physics.scene.body  # type: ignore[attr-defined]
    physics.handle(PhysicsReset(time=0.0), physics.time, "test")
    q = body.state()[0].copy()
    head = JOINTS.index("head") * 3 + 2
    q[head] = 3.0  # far beyond the head's turn
    physics.handle(PhysicsPosture(time=0.0, duration=0.0, values=tuple(q)), physics.time, "graphics")
    assert not physics.rejected
    target = physics.scene.joint_track.sample(physics.time + 1.0)[0]  # type: ignore[attr-defined]
    assert target[head] <= body.upper[head] + 1e-9
    physics.handle(PhysicsPosture(time=0.0, duration=0.1, values=(0.1,) * 5), physics.time, "graphics")
    assert physics.rejected["PhysicsPosture"] == 1  # wrong length: rejected with a reason, not a crash
    physics.handle(PhysicsReset(time=0.0), physics.time, "test")


def test_without_physics_the_editor_poses_the_shipped_body(tmp_path: Path) -> None:
    graphics = GraphicsCore(GraphicsSettings(latency=0.0, clock="rig"))
    server = ViewServer(graphics, kit_dir=tmp_path)
    reply = server.handle_page_message(json.dumps({"type": "poser_on"}))
    assert reply is not None and reply["body"] == "rest"
    info = load_character()
    assert graphics.names == info.names
    frame = graphics.frame_at(0.0)
    assert frame is not None
    _same_frames(frame.pose, rest_poser().pose())
    server.handle_page_message(json.dumps({"type": "poser", "angles": {"left_knee": [-60, 0, 0]}, "drive": False}))
    assert not [o for o in graphics.step(0.1) if o.to == "physics"]  # not driving: nothing for physics
    saved = server.handle_page_message(json.dumps({"type": "save_pose", "name": "BASS.left_foot.DOWN"}))
    assert saved is not None and saved["ok"] is True
    key = KeyPoses.load(tmp_path / "poses.yaml").poses["BASS.left_foot.DOWN"]
    assert key.joints["left_knee"] == (-60.0, 0.0, 0.0) and set(key.effectors) == {
        "left_hand", "right_hand", "left_foot", "right_foot"}
    server.handle_page_message(json.dumps({"type": "poser_off"}))
    assert graphics.frame_at(0.0) is None
