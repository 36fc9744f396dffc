"""``batteur render SCORE --gltf``: the performance (the drummer's links and the kit) as one animated glTF file.

One render of tests/graphics/tiny_score.txt (four strokes, about 4 s of rig
time) is shared by the checks of its file; the Khronos glTF-Validator runs
when node and services/graphics/web's ``npm ci`` are there (as in
tests/graphics/test_export.py).
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pygltflib
import pytest

from batteur import render
from common.kit import load_kit
from services.graphics.export import gltf as gltf_export

ROOT = Path(__file__).resolve().parents[2]
SCORE = ROOT / "tests" / "graphics" / "tiny_score.txt"
WEB = ROOT / "services" / "graphics" / "web"


@pytest.fixture(scope="module")
def rendered(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("gltf") / "out"
    assert render.main([str(SCORE), "-o", str(out), "--quiet", "--gltf"]) == 0
    return out


def bvh_frames(path: Path) -> tuple[int, float]:
    """(frame count, frame time in seconds) of a BVH file."""
    text = path.read_text()
    count = re.search(r"^Frames:\s*(\d+)", text, re.M)
    step = re.search(r"^Frame Time:\s*([0-9.]+)", text, re.M)
    assert count and step
    return int(count.group(1)), float(step.group(1))


def load(path: Path) -> pygltflib.GLTF2:
    gltf = pygltflib.GLTF2().load(str(path))
    assert gltf is not None
    return gltf


def channel_output(gltf: pygltflib.GLTF2, node: int, target: str) -> np.ndarray:
    """The keyframe values of ``node``'s ``target`` channel (translation (N, 3) or rotation (N, 4))."""
    animation = gltf.animations[0]
    channel = next(c for c in animation.channels if c.target.node == node and c.target.path == target)
    accessor = gltf.accessors[animation.samplers[channel.sampler].output]
    view = gltf.bufferViews[accessor.bufferView]
    data = gltf.binary_blob()[view.byteOffset:view.byteOffset + view.byteLength]
    return np.frombuffer(data, dtype=np.float32).reshape(accessor.count, -1)


def test_gltf_has_one_animation_as_long_as_the_bvh_at_its_rate(rendered: Path) -> None:
    report = json.loads((rendered / "report.json").read_text())
    entry = report["gltf"]
    assert entry["file"] == "performance.glb" and (rendered / "performance.glb").is_file()
    frames, frame_time = bvh_frames(rendered / "performance.bvh")
    gltf = load(rendered / "performance.glb")
    assert len(gltf.animations) == 1
    animation = gltf.animations[0]
    times = gltf.accessors[animation.samplers[0].input]
    assert times.count == frames == entry["frames"]  # one key per BVH frame, the same poses at the same rate
    assert entry["rate_hz"] == pytest.approx(1 / frame_time, rel=1e-6) == 60.0
    assert times.max[0] == pytest.approx((frames - 1) * frame_time, abs=1e-5)
    # the poses span the render: from its first pose (1 ms, physics' first step) to its end, within a frame
    assert entry["start_s"] + times.max[0] == pytest.approx(report["duration_s"], abs=frame_time)


def test_gltf_holds_the_drummers_links_and_the_kit(rendered: Path) -> None:
    gltf = load(rendered / "performance.glb")
    names = [n.name for n in gltf.nodes]
    animated = {gltf.nodes[c.target.node].name for c in gltf.animations[0].channels}
    bvh_joints = set(re.findall(r"(?:ROOT|JOINT)\s+(\S+)", (rendered / "performance.bvh").read_text()))
    assert len(bvh_joints) >= 20 and bvh_joints <= animated  # every body link of the BVH moves in the glTF
    kit = load_kit("default")
    for obj in kit.objects:
        assert f"kit_{obj.id}" in names, obj.id
        assert gltf.nodes[names.index(f"kit_{obj.id}")].mesh is not None
    # the kit moves with physics' kit links: the ride's disc is the child of the ride's animated link
    ride_link = gltf.nodes[names.index("kit.ride")]
    assert names.index("kit_ride") in ride_link.children and "kit.ride" in animated


def test_gltf_animates_the_hihat_opening_and_the_pedal(rendered: Path) -> None:
    """The score plays the closed hi-hat with the pedal down: its top plate and the pedal's footboard move."""
    gltf = load(rendered / "performance.glb")
    names = [n.name for n in gltf.nodes]
    top = channel_output(gltf, names.index("kit.hihat.top"), "translation")
    assert np.ptp(top[:, 2]) > 0.005  # metres (z up under the root): the plate closes on the bottom one
    assert names.index("kit_hihat") in gltf.nodes[names.index("kit.hihat.top")].children
    board = channel_output(gltf, names.index("kit.hihat_pedal.footboard"), "rotation")
    assert np.ptp(board[:, 0]) > 0.05  # the footboard tilts about its heel (quaternion x)
    assert names.index("kit_hihat_pedal") in gltf.nodes[names.index("kit.hihat_pedal.footboard")].children


def test_gltf_passes_the_khronos_validator(rendered: Path) -> None:
    if shutil.which("node") is None or not (WEB / "node_modules" / "gltf-validator").is_dir():
        pytest.skip("needs node and `npm ci` in services/graphics/web (Khronos gltf-validator)")
    result = subprocess.run(["node", str(WEB / "validate-gltf.mjs"), str(rendered / "performance.glb")],
                            capture_output=True, text=True, timeout=60, check=False)
    report: dict[str, Any] = json.loads(result.stdout.splitlines()[0])
    assert (report["numErrors"], report["numWarnings"]) == (0, 0), report["messages"]
    assert result.returncode == 0


def test_render_again_without_gltf_removes_the_old_file(rendered: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    shutil.copytree(rendered, out)
    assert render.main([str(SCORE), "-o", str(out), "--quiet"]) == 0
    assert not (out / "performance.glb").exists()  # not left to be taken for this performance's
    assert "gltf" not in json.loads((out / "report.json").read_text())


def test_gltf_with_jobs(tmp_path: Path) -> None:
    """Segments on two processes: the parent keeps the merged poses, as for --video."""
    out = tmp_path / "out"
    assert render.main([str(SCORE), "-o", str(out), "--quiet", "--gltf", "--jobs", "2", "--segment", "2"]) == 0
    frames, _ = bvh_frames(out / "performance.bvh")
    gltf = load(out / "performance.glb")
    assert gltf.accessors[gltf.animations[0].samplers[0].input].count == frames


def test_gltf_refused_for_the_strike_scene(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exited:
        render.main(["--strikes", "0.2:3", "-o", str(tmp_path / "s"), "--gltf"])
    assert exited.value.code == 2
    assert "--gltf exports a SCORE" in capsys.readouterr().err
    assert not (tmp_path / "s").exists()


def test_a_failing_export_leaves_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    def full_disk(*args: object, **kwargs: object) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(gltf_export, "write_gltf", full_disk)
    out = tmp_path / "out"
    assert render.main([str(SCORE), "-o", str(out), "--quiet", "--gltf"]) == 1
    assert "--gltf: [Errno 28] No space left on device" in capsys.readouterr().err
    assert not out.exists()  # the WAV, BVH and impacts were staged, not written
