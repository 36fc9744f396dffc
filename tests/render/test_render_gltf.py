"""``batteur render SCORE --gltf``: the performance (the drummer's links and the kit) as one animated glTF file.

One render of tests/graphics/tiny_score.txt (four strokes, about 4 s of rig
time) is shared by the checks of its file (tests/conftest.py's ``tiny_gltf_render``, which other modules read
too); the Khronos glTF-Validator runs
when node and services/graphics/web's ``npm ci`` are there (as in
tests/graphics/test_export.py).
"""

from __future__ import annotations

import csv
import json
import math
import re
import shutil
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pygltflib
import pytest
from scipy.spatial.transform import Rotation

from batteur import render
from common.gesture.bvh import forward_kinematics, read_bvh
from common.kit import load_kit
from services.graphics.export import gltf as gltf_export
from services.graphics.export.bvh import THRONE_JOINT
from services.graphics.video import STICK_TIP
from tests.graphics.gltf_reading import accessor, load

ROOT = Path(__file__).resolve().parents[2]
SCORE = ROOT / "tests" / "graphics" / "tiny_score.txt"
WEB = ROOT / "services" / "graphics" / "web"


@pytest.fixture(scope="module")
def rendered(tiny_gltf_render: Path) -> Path:
    """``SCORE`` rendered with ``--gltf`` (and the BVH on the WAV's clock, the default): tests/conftest.py's one
    render, read only."""
    return tiny_gltf_render


def bvh_frames(path: Path) -> tuple[int, float]:
    """(frame count, frame time in seconds) of a BVH file."""
    text = path.read_text()
    count = re.search(r"^Frames:\s*(\d+)", text, re.M)
    step = re.search(r"^Frame Time:\s*([0-9.]+)", text, re.M)
    assert count and step
    return int(count.group(1)), float(step.group(1))


def channel_output(gltf: pygltflib.GLTF2, node: int, target: str) -> np.ndarray:
    """The keyframe values of ``node``'s ``target`` channel (translation (N, 3) or rotation (N, 4))."""
    animation = gltf.animations[0]
    channel = next(c for c in animation.channels if c.target.node == node and c.target.path == target)
    return accessor(gltf, animation.samplers[channel.sampler].output)


def key_times(gltf: pygltflib.GLTF2) -> np.ndarray:
    """The animation's key times, seconds (every sampler shares one input)."""
    return accessor(gltf, gltf.animations[0].samplers[0].input)[:, 0]


def trs(node: pygltflib.Node) -> np.ndarray:
    """A node's rest transform (its translation, rotation and scale) as a 4x4 matrix."""
    m = np.eye(4)
    m[:3, :3] = Rotation.from_quat(node.rotation or [0, 0, 0, 1]).as_matrix() * np.asarray(node.scale or [1, 1, 1])
    m[:3, 3] = node.translation or [0, 0, 0]
    return m


def link_key(gltf: pygltflib.GLTF2, link: int, k: int) -> np.ndarray:
    """Link node ``link``'s transform under the root (z up) at key ``k``: its keys composed with its parents' (a
    body link is a joint of the skin, keyed relative to its parent joint; a kit link's parent is the root)."""
    parent_of = {c: i for i, n in enumerate(gltf.nodes) for c in n.children or []}
    root = gltf.scenes[0].nodes[0]
    m = np.eye(4)
    node = link
    while node != root:
        local = trs(gltf.nodes[node])
        channels = {c.target.path for c in gltf.animations[0].channels if c.target.node == node}
        if "rotation" in channels:
            local[:3, :3] = Rotation.from_quat(channel_output(gltf, node, "rotation")[k]).as_matrix()
        if "translation" in channels:
            local[:3, 3] = channel_output(gltf, node, "translation")[k]
        m = local @ m
        node = parent_of[node]
    return m


def mesh_bounds(gltf: pygltflib.GLTF2, node: int, parent: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(lowest, highest) corner (3,) of mesh node ``node``'s bounding box placed by ``parent`` @ its transform."""
    position = gltf.accessors[gltf.meshes[gltf.nodes[node].mesh].primitives[0].attributes.POSITION]
    lo, hi = np.asarray(position.min), np.asarray(position.max)
    corners = np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    placed = (parent @ trs(gltf.nodes[node]) @ corners.T).T[:, :3]
    return placed.min(axis=0), placed.max(axis=0)


def impacts(out: Path) -> list[dict[str, str]]:
    with (out / "impacts.csv").open(newline="") as f:
        return list(csv.DictReader(f))


def test_gltf_has_one_animation_at_the_bvhs_rate_on_the_wavs_clock(rendered: Path) -> None:
    """Key k is at WAV time k / rate (rig time k / rate - latency_s): the file and performance.wav imported at 0
    line up, the first pose held until the motion starts."""
    report = json.loads((rendered / "report.json").read_text())
    entry = report["gltf"]
    assert entry["file"] == "performance.glb" and (rendered / "performance.glb").is_file()
    _, frame_time = bvh_frames(rendered / "performance.bvh")
    gltf = load(rendered / "performance.glb")
    assert len(gltf.animations) == 1
    times = key_times(gltf)
    assert len(times) == entry["frames"]
    assert entry["rate_hz"] == pytest.approx(1 / frame_time, rel=1e-6) == 60.0
    assert times[0] == 0.0 and np.allclose(np.diff(times), frame_time, atol=1e-5)
    assert entry["start_s"] == -report["latency_s"] == -0.05  # the rig time of key 0
    # the motion lasts as the WAV does: to the render's end, within a frame
    assert times[-1] == pytest.approx(report["duration_s"], abs=frame_time)
    # the first pose (rig time 1 ms, WAV time 0.051 s) is held from key 0 until it
    pelvis = channel_output(gltf, [n.name for n in gltf.nodes].index("pelvis"), "translation")
    held = times <= 0.001 + report["latency_s"]
    assert held.sum() == 4 and np.all(pelvis[held] == pelvis[0])


def test_gltf_shows_each_strike_where_the_wav_has_it(rendered: Path) -> None:
    """The right stick's tip is lowest on the hi-hat at the key of its impact's WAV time (rig time + latency_s),
    within one frame; the file's clock before was the first pose's, 51 ms (3 frames) early."""
    report = json.loads((rendered / "report.json").read_text())
    gltf = load(rendered / "performance.glb")
    times = key_times(gltf)
    stick = [n.name for n in gltf.nodes].index("right_stick")  # a joint of the skin: its pose composed up the tree
    tip_z = np.array([(link_key(gltf, stick, k) @ [0.0, STICK_TIP, 0.0, 1.0])[2] for k in range(len(times))])
    strikes = [float(i["time"]) for i in impacts(rendered) if i["part"] == "right_stick_tip"]
    assert len(strikes) == 2
    for t in strikes:
        heard = t + report["latency_s"]  # performance.wav's time of the strike
        near = np.flatnonzero(np.abs(times - heard) < 0.15)
        lowest = near[np.argmin(tip_z[near])]
        assert times[lowest] == pytest.approx(heard, abs=1 / 60 + 1e-3)


def test_gltf_draws_nothing_at_the_origin(rendered: Path) -> None:
    """Every mesh sits where its object is: none at the world origin (a stray box there before: the stands'
    link, which is at the origin, drawn as a body box). The body's boxes are one skinned mesh, a scene root whose
    vertices are where the first pose has them (y up)."""
    gltf = load(rendered / "performance.glb")
    root = gltf.scenes[0].nodes[0]
    placed: list[tuple[int, np.ndarray]] = [(c, trs(gltf.nodes[c])) for c in gltf.nodes[root].children]
    placed += [(n, np.eye(4)) for n in gltf.scenes[0].nodes[1:]]
    seen = 0
    while placed:
        node, m = placed.pop()
        if gltf.nodes[node].mesh is not None:
            lo, hi = mesh_bounds(gltf, node, m @ np.linalg.inv(trs(gltf.nodes[node])))
            seen += 1
            assert np.linalg.norm((lo + hi) / 2) > 0.1, gltf.nodes[node].name  # metres
        placed += [(c, m @ trs(gltf.nodes[c])) for c in gltf.nodes[node].children or []]
    assert seen > 25  # the kit's meshes and the skinned body (was > 40: a node per body link's box)


def test_gltf_draws_the_kick_beater_reaching_the_head(rendered: Path) -> None:
    """The beater's ball meets the kick's head between the keys about the kick's impact (it was a 5 cm box at its
    axle, 12 cm short of the head), and does not sink into it deeper than physics presses it (q = 0: 1.1 cm)."""
    report = json.loads((rendered / "report.json").read_text())
    gltf = load(rendered / "performance.glb")
    beater = [n.name for n in gltf.nodes].index("kit.kick_pedal.beater")
    head_y = load_kit("default").object("kick").position[1]  # the head faces the drummer (-y)
    heard = next(float(i["time"]) for i in impacts(rendered) if i["part"] == "kick_beater") + report["latency_s"]
    times = key_times(gltf)

    def gap(k: int) -> float:
        """From the front of the beater's ball to the head at key ``k``, metres (< 0: pressed into it)."""
        return head_y - max(mesh_bounds(gltf, c, link_key(gltf, beater, k))[1][1] for c in gltf.nodes[beater].children)

    after = int(np.searchsorted(times, heard))
    assert gap(after - 1) > 0.0 and gap(after) < 0.005
    assert min(gap(k) for k in range(len(times))) > -0.025


def test_gltf_hihat_plates_do_not_overlap(rendered: Path) -> None:
    """The top plate is drawn above its link frame, as physics has it: closed, it rests on the bottom plate
    instead of sinking into it."""
    gltf = load(rendered / "performance.glb")
    names = [n.name for n in gltf.nodes]
    top, bottom = names.index("kit.hihat.top"), names.index("kit.hihat.bottom")
    top_mesh, bottom_mesh = names.index("kit_hihat"), names.index("kit_hihat_bottom")
    lowest_gap = min(mesh_bounds(gltf, top_mesh, link_key(gltf, top, k))[0][2]
                     - mesh_bounds(gltf, bottom_mesh, link_key(gltf, bottom, k))[1][2]
                     for k in range(len(key_times(gltf))))
    assert 0.0 <= lowest_gap < 0.005  # metres: closed (the pedal is down in this score), not overlapping


def test_gltf_holds_the_drummers_links_and_the_kit(rendered: Path) -> None:
    gltf = load(rendered / "performance.glb")
    names = [n.name for n in gltf.nodes]
    animated = {gltf.nodes[c.target.node].name for c in gltf.animations[0].channels}
    bvh_joints = set(re.findall(r"(?:ROOT|JOINT)\s+(\S+)", (rendered / "performance.bvh").read_text()))
    bvh_joints.discard(THRONE_JOINT)  # the throne's frame under the pelvis, no link
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


def test_gltf_body_ends_where_the_bvh_does(rendered: Path) -> None:
    """The render gives the export the BVH's End Sites (the body physics built, ``render.body_end_sites``): each
    stick's tip joint is physics' bead centre, each foot's box reaches the ball of the foot (without them a foot
    is a cube about its ankle)."""
    gltf = load(rendered / "performance.glb")
    sites = render.body_end_sites(render.RenderOptions())
    names = [n.name for n in gltf.nodes]
    skin = gltf.skins[0]
    inverse = accessor(gltf, skin.inverseBindMatrices).reshape(-1, 4, 4).transpose(0, 2, 1).astype(float)
    mesh = gltf.meshes[next(n.mesh for n in gltf.nodes if n.skin is not None)]
    for side in ("left", "right"):
        tip = gltf.nodes[names.index(f"{side}_stick_tip")]
        assert names.index(f"{side}_stick_tip") in gltf.nodes[names.index(f"{side}_stick")].children
        np.testing.assert_allclose(tip.translation, sites[f"{side}_stick"], atol=1e-6)
        joint = [gltf.nodes[j].name for j in skin.joints].index(f"{side}_foot")
        ball = np.asarray(sites[f"{side}_foot"])
        reach = []
        for primitive in mesh.primitives:  # the bind pose's vertices in the foot's frame (its link's, z up)
            bound = accessor(gltf, primitive.attributes.JOINTS_0)[:, 0] == joint
            pos = accessor(gltf, primitive.attributes.POSITION).astype(float)[bound]
            local = (inverse[joint] @ np.c_[pos, np.ones(len(pos))].T).T[:, :3]
            reach += list(local @ ball / np.linalg.norm(ball))
        assert max(reach) == pytest.approx(np.linalg.norm(ball), abs=1e-5)  # metres


def test_the_bvh_faces_as_the_gltf(rendered: Path) -> None:
    """The BVH and the glTF of one render put each joint at the same place at each frame (y up, metres, the drummer
    facing +z, report.json's ``bvh.facing``): the BVH faced -z (the sticks struck at z ~ -0.42 m, the glTF's at
    +0.42 m), so a clip retargeted from it, or the two imported together, were half a turn apart."""
    report = json.loads((rendered / "report.json").read_text())
    assert report["bvh"]["facing"] == "+z"
    gltf = load(rendered / "performance.glb")
    names = [n.name for n in gltf.nodes]
    root = trs(gltf.nodes[names.index("batteur")])  # the file's root: z up to y up
    placed = forward_kinematics(read_bvh(rendered / "performance.bvh"))
    frames = min(len(key_times(gltf)), len(placed["pelvis"]))
    assert frames > 100
    for k in (0, frames // 3, frames // 2, frames - 1):
        for link, joint in (("pelvis", "pelvis"), ("head", "head"), ("left_foot", "left_foot"),
                            ("right_stick", "right_stick"), ("right_stick_tip", "right_stick_end")):
            at = (root @ link_key(gltf, names.index(link), k))[:3, 3]
            assert np.linalg.norm(at - placed[joint][k]) < 1e-4, (k, link, at, placed[joint][k])  # metres


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
    report = json.loads((out / "report.json").read_text())
    times = key_times(load(out / "performance.glb"))
    assert times[0] == 0.0 and len(times) == report["gltf"]["frames"] == math.floor(report["duration_s"] * 60) + 1


def test_gltf_refused_for_the_strike_scene(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert render.main(["--strikes", "0.2:3", "-o", str(tmp_path / "s"), "--gltf"]) == 2  # one line, no usage
    assert capsys.readouterr().err == ("batteur render: error: --gltf exports a SCORE's performance (the strike scene "
                                       "has no body to export)\n")
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
