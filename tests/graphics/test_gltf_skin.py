"""The glTF export's skeleton and skin: an armature an animator can retarget, drawing what the rigid nodes drew.

The body's links are joint nodes in the BVH's tree (the same names and parents, physics' ``seat`` joint included),
animated by their local rotations; the links' boxes are one skinned mesh bound weight 1 to their link's joint. A
small numpy glTF evaluator (node TRS, animation keys, linear blend skinning) places the skinned vertices, which must
be where each link's box is at its pose (what the file drew with one rigid node per link before).
"""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pygltflib
import pytest
from scipy.spatial.transform import Rotation

from common.gesture.bvh import read_bvh
from common.kit import load_kit
from services.graphics.export import write_bvh, write_gltf
from services.graphics.export.bvh import THRONE_JOINT
from services.graphics.export.gltf import ROOT_ROTATION, _box
from services.graphics.figure import synthetic_performance
from services.graphics.sequence import PoseSequence, normalize_quats
from tests.graphics.gltf_reading import accessor, load
from tests.graphics.physics_poses import posed_frames

WEB = Path(__file__).resolve().parents[2] / "services" / "graphics" / "web"
LINK_SIZE_M = 0.05
FRAMES = (0, 2, 3)
"""Keys evaluated: the bind pose (the first) and two with the pelvis rocked (physics_poses) or moved."""


@pytest.fixture(scope="module")
def physics_poses() -> PoseSequence:
    """Physics' own frames (links and kit links) with the pelvis rocked on the seat and limbs bent differently in
    each frame (as tests/graphics/test_bvh_throne.py; the seat joint only physics' character has)."""
    rocks = ((0.0, 0.0, 0.0), (5.0, 0.0, 0.0), (10.0, 10.0, 10.0), (-10.0, 10.0, -10.0))
    return posed_frames([{"seat": rock, "left_hip": (70.0 + 5 * k, -8.0, 5.0), "right_knee": (-80.0 + 10 * k, 0.0, 0.0),
                          "right_elbow": (60.0, 0.0, 5 * k), "left_wrist": (10.0 * k, 0.0, 0.0)}
                         for k, rock in enumerate(rocks)])


def global_transforms(gltf: pygltflib.GLTF2, key: int) -> dict[int, np.ndarray]:
    """Every node's global 4x4 transform at animation key ``key`` (animated paths from the key, others the
    node's own translation/rotation/scale)."""
    animated: dict[tuple[int, str], np.ndarray] = {}
    for animation in gltf.animations:
        for channel in animation.channels:
            output = accessor(gltf, animation.samplers[channel.sampler].output)
            animated[(channel.target.node, channel.target.path)] = output[key].astype(float)
    out: dict[int, np.ndarray] = {}

    def visit(node: int, parent: np.ndarray) -> None:
        n = gltf.nodes[node]
        t = animated.get((node, "translation"), n.translation or [0.0, 0.0, 0.0])
        r = animated.get((node, "rotation"), n.rotation or [0.0, 0.0, 0.0, 1.0])
        s = animated.get((node, "scale"), n.scale or [1.0, 1.0, 1.0])
        local = np.eye(4)
        local[:3, :3] = Rotation.from_quat(r).as_matrix() * np.asarray(s, dtype=float)
        local[:3, 3] = t
        out[node] = parent @ local
        for child in n.children or []:
            visit(child, out[node])

    for root in gltf.scenes[gltf.scene].nodes:
        visit(root, np.eye(4))
    return out


def skinned_vertices(gltf: pygltflib.GLTF2, key: int) -> np.ndarray:
    """The skinned meshes' vertices (all primitives, in order) at key ``key``: sum of weight * joint global *
    inverse bind matrix * position (glTF 2.0 spec, "Skins"), metres, y up."""
    g = global_transforms(gltf, key)
    placed = []
    for node in gltf.nodes:
        if node.skin is None:
            continue
        skin = gltf.skins[node.skin]
        inverse = accessor(gltf, skin.inverseBindMatrices).reshape(-1, 4, 4).transpose(0, 2, 1).astype(float)
        joint_matrices = np.stack([g[j] for j in skin.joints]) @ inverse
        for primitive in gltf.meshes[node.mesh].primitives:
            pos = accessor(gltf, primitive.attributes.POSITION).astype(float)
            joints = accessor(gltf, primitive.attributes.JOINTS_0).astype(int)
            weights = accessor(gltf, primitive.attributes.WEIGHTS_0).astype(float)
            homogeneous = np.c_[pos, np.ones(len(pos))]
            v = np.zeros((len(pos), 4))
            for c in range(4):
                v += weights[:, c:c + 1] * np.einsum("nij,nj->ni", joint_matrices[joints[:, c]], homogeneous)
            placed.append(v[:, :3])
    return np.concatenate(placed)


def rigid_vertices(sequence: PoseSequence, key: int, names: list[str]) -> np.ndarray:
    """Each of ``names``' boxes (the file's link size; a stick's half, a head's 2.5 times) placed by its pose at
    ``key`` under the file's root (z up -> y up): what the rigid link nodes drew. Sticks after the body, as the
    file's primitives (body material, stick material)."""
    box = _box()[0].astype(float)
    root = Rotation.from_quat(ROOT_ROTATION)
    out = []
    for name in sorted(names, key=lambda n: ("stick" in n, sequence.names.index(n))):
        pose = sequence.values[key, sequence.names.index(name)]
        size = LINK_SIZE_M * (0.5 if "stick" in name else (2.5 if name.endswith("head") else 1.0))
        out.append(root.apply(Rotation.from_quat(normalize_quats(pose[3:])).apply(box * size) + pose[:3]))
    return np.concatenate(out)


def bvh_tree(path: Path) -> dict[str, str | None]:
    """Joint name -> its parent's name (None: the root) of a BVH file."""
    joints = read_bvh(path).joints
    return {j.name: None if j.parent < 0 else joints[j.parent].name for j in joints}


def gltf_tree(gltf: pygltflib.GLTF2) -> dict[str, str | None]:
    """The skin's joint name -> its parent joint's name (None: the skeleton's root)."""
    skin = gltf.skins[0]
    parent_of = {c: i for i, n in enumerate(gltf.nodes) for c in n.children or []}
    joints = set(skin.joints)
    return {gltf.nodes[j].name: gltf.nodes[parent_of[j]].name if parent_of.get(j) in joints else None
            for j in skin.joints}


def validate(path: Path) -> dict[str, Any]:
    if shutil.which("node") is None or not (WEB / "node_modules" / "gltf-validator").is_dir():
        pytest.skip("needs node and `npm ci` in services/graphics/web (Khronos gltf-validator)")
    result = subprocess.run(["node", str(WEB / "validate-gltf.mjs"), str(path)], capture_output=True, text=True,
                            timeout=60, check=False)
    report: dict[str, Any] = json.loads(result.stdout.splitlines()[0])
    report["returncode"] = result.returncode
    return report


def test_the_skin_joints_are_the_bvhs_in_the_same_tree(physics_poses: PoseSequence, tmp_path: Path) -> None:
    write_bvh(physics_poses, tmp_path / "p.bvh")
    info = write_gltf(physics_poses, tmp_path / "p.glb", kit=load_kit("default"))
    gltf = load(tmp_path / "p.glb")
    assert len(gltf.skins) == 1
    want = bvh_tree(tmp_path / "p.bvh")
    assert THRONE_JOINT in want and want[THRONE_JOINT] == "pelvis" and want["left_thigh"] == THRONE_JOINT
    assert gltf_tree(gltf) == want
    skin = gltf.skins[0]
    assert [gltf.nodes[j].name for j in skin.joints] == list(want)  # the BVH's order: parents first
    assert info.joints == len(want)
    # the root joint (the pelvis) hangs from the file's root node (z up -> y up), as the link nodes do
    root = next(n for n in gltf.nodes if n.name == "batteur")
    assert skin.joints[0] in root.children and gltf.nodes[skin.skeleton].name == "pelvis"
    # every joint turns: its rotation is animated (the pelvis' translation too)
    animated = {(gltf.nodes[c.target.node].name, c.target.path) for c in gltf.animations[0].channels}
    assert all((name, "rotation") in animated for name in want) and ("pelvis", "translation") in animated


@pytest.mark.parametrize("source", ["physics", "synthetic"])
def test_skinned_vertices_are_where_the_rigid_boxes_were(source: str, physics_poses: PoseSequence,
                                                          tmp_path: Path) -> None:
    """At 3 keys every vertex of the skinned body is within 1e-5 m of the box its link's pose places (what the
    rigid link nodes drew), for physics' character (seat joint, rocked pelvis) and another skeleton."""
    seq = physics_poses if source == "physics" else synthetic_performance(duration=1.5, rate_hz=60.0)[0]
    write_gltf(seq, tmp_path / "p.glb", kit=load_kit("default"), link_size=LINK_SIZE_M)
    gltf = load(tmp_path / "p.glb")
    skin = gltf.skins[0]
    links = [gltf.nodes[j].name for j in skin.joints if gltf.nodes[j].name in seq.names]
    assert not any(n.mesh is not None and n.name.endswith("_mesh") for n in gltf.nodes)  # no rigid body box left
    for key in FRAMES:
        got = skinned_vertices(gltf, key)
        want = rigid_vertices(seq, key, links)
        assert got.shape == want.shape
        assert np.abs(got - want).max() < 1e-5, key  # metres
    # each vertex has one joint, weight 1
    for primitive in gltf.meshes[next(n.mesh for n in gltf.nodes if n.skin is not None)].primitives:
        weights = accessor(gltf, primitive.attributes.WEIGHTS_0)
        assert np.all(weights[:, 0] == 1.0) and np.all(weights[:, 1:] == 0.0)


def test_the_skinned_file_passes_the_khronos_validator(physics_poses: PoseSequence, tmp_path: Path) -> None:
    for suffix in (".glb", ".gltf"):
        path = tmp_path / f"p{suffix}"
        write_gltf(physics_poses, path, kit=load_kit("default"))
        report = validate(path)
        assert (report["numErrors"], report["numWarnings"]) == (0, 0), report["messages"]
        assert report["info"]["hasSkins"] is True
        assert report["returncode"] == 0
