"""BVH and glTF export: re-imported with independent readers (bvhio; Khronos glTF-Validator, pygltflib)."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pygltflib
import pytest

from common.kit import kit_hardware, load_kit
from services.graphics.export import write_bvh, write_gltf
from services.graphics.export.bvh import DEFAULT_FACING, Y_UP
from services.graphics.figure import LINK_NAMES, synthetic_performance
from services.graphics.sequence import PoseSequence

WEB = Path(__file__).resolve().parents[2] / "services" / "graphics" / "web"


@pytest.fixture(scope="module")
def performance() -> PoseSequence:
    return synthetic_performance(duration=1.5, rate_hz=60.0)[0]


def test_bvh_reimports_with_joint_and_frame_counts_and_positions(performance: PoseSequence, tmp_path: Path) -> None:
    bvhio = pytest.importorskip("bvhio")
    path = tmp_path / "perf.bvh"
    info = write_bvh(performance, path)
    container = bvhio.readAsBvh(str(path))
    assert container.FrameCount == len(performance.times) == info.frames == 91
    assert container.FrameTime == pytest.approx(1 / 60, abs=1e-6)
    root = bvhio.readAsHierarchy(str(path))
    layout = root.layout()
    assert len(layout) == len(LINK_NAMES) == 23
    assert {joint.Name for joint, _, _ in layout} == set(LINK_NAMES)
    # the reader's own forward kinematics puts every joint where the input had it (y-up file frame)
    for frame in (0, 45, 90):
        root.loadPose(frame)
        for joint, _, _ in layout:
            want = Y_UP[DEFAULT_FACING] @ performance.values[frame, LINK_NAMES.index(joint.Name), :3]
            assert np.allclose(list(joint.PositionWorld), want, atol=1e-4), (frame, joint.Name)


def test_bvh_leaves_out_kit_links_and_resamples(performance: PoseSequence, tmp_path: Path) -> None:
    bvhio = pytest.importorskip("bvhio")
    # a physics-driven cymbal link is not part of the body tree
    extra = np.concatenate([performance.values, performance.values[:, :1]], axis=1)
    extra[:, -1, :3] = [0.6, 0.6, 1.0]
    seq = PoseSequence([*performance.names, "ride"], performance.times, extra)
    info = write_bvh(seq, tmp_path / "r.bvh", rate_hz=30.0, scale=100.0)
    assert info.skipped == ["ride"]
    container = bvhio.readAsBvh(str(tmp_path / "r.bvh"))
    assert container.FrameCount == 46  # 1.5 s at 30 Hz, both ends included
    assert len(bvhio.readAsHierarchy(str(tmp_path / "r.bvh")).layout()) == 23


def test_bvh_without_a_body_is_an_error(tmp_path: Path) -> None:
    seq = PoseSequence(["crash"], np.array([0.0]), np.array([[[0, 0, 1, 0, 0, 0, 1]]], dtype=float))
    with pytest.raises(ValueError, match="no body root"):
        write_bvh(seq, tmp_path / "x.bvh")


def _validate(path: Path) -> dict[str, object]:
    if shutil.which("node") is None or not (WEB / "node_modules" / "gltf-validator").is_dir():
        pytest.skip("needs node and `npm ci` in services/graphics/web (Khronos gltf-validator)")
    result = subprocess.run(["node", str(WEB / "validate-gltf.mjs"), str(path)], capture_output=True, text=True,
                            timeout=60, check=False)
    assert result.stdout, result.stderr
    report: dict[str, object] = json.loads(result.stdout.splitlines()[0])
    report["returncode"] = result.returncode
    return report


@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
def test_gltf_validates_and_has_the_animation(performance: PoseSequence, tmp_path: Path, suffix: str) -> None:
    path = tmp_path / f"perf{suffix}"
    info = write_gltf(performance, path, kit=load_kit("default"))
    assert (info.links, info.keyframes) == (23, 91)
    gltf = pygltflib.GLTF2().load(str(path))
    assert gltf is not None
    animation = gltf.animations[0]
    # a joint per link (the skin's): rotation keys each, translation keys for the root and a joint whose offset moves
    assert info.joints == 23 and len(gltf.skins) == 1
    paths = [c.target.path for c in animation.channels]
    assert paths.count("rotation") == 23 and 1 <= paths.count("translation") <= 23
    times = gltf.accessors[animation.samplers[0].input]
    assert times.count == 91 and times.max == pytest.approx([1.5])
    report = _validate(path)
    assert report["numErrors"] == 0, report["messages"]
    assert report["returncode"] == 0


def test_validator_rejects_a_broken_file(performance: PoseSequence, tmp_path: Path) -> None:
    """The validator is a real check: a file whose animation points past its data fails."""
    path = tmp_path / "broken.gltf"
    write_gltf(performance, path)
    data = json.loads(path.read_text())
    data["accessors"][data["animations"][0]["samplers"][0]["output"]]["count"] *= 50
    path.write_text(json.dumps(data))
    report = _validate(path)
    assert int(report["numErrors"]) > 0  # type: ignore[call-overload]
    assert report["returncode"] == 1


@pytest.mark.parametrize("name", ["default", "double_pedal"])
def test_the_gltf_beaters_are_physics_own(name: str, performance: PoseSequence, tmp_path: Path) -> None:
    """Each beater link of a render is drawn as the rod and ball physics builds (``kit_hardware``, which
    tests/graphics/test_hardware.py checks against physics' bodies): the ball at the rod's end, the rod's radius."""
    kit = load_kit(name)
    beaters = kit_hardware(kit).beaters
    links = [f"kit.{b.pedal}.beater" for b in beaters]
    poses = np.repeat(performance.values[:, :1], len(links), axis=1)
    seq = PoseSequence([*performance.names, *links], performance.times,
                       np.concatenate([performance.values, poses], axis=1))
    path = tmp_path / "beaters.glb"
    write_gltf(seq, path, kit=kit)
    nodes = {n.name: n for n in pygltflib.GLTF2().load(str(path)).nodes}
    for beater in beaters:
        stem = f"kit_{beater.pedal}_beater"
        assert nodes[f"{stem}_ball"].translation == pytest.approx([0.0, 0.0, beater.rod_length], abs=1e-6)  # metres
        assert nodes[f"{stem}_ball"].scale == pytest.approx([beater.ball_radius] * 3)
        assert nodes[stem].scale == pytest.approx([beater.rod_radius, beater.rod_radius, beater.rod_length], abs=1e-6)
