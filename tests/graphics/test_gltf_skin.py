"""The glTF export's skeleton and skin: an armature an animator can retarget, each link's shape moving with it.

The body's links are joint nodes in the BVH's tree (the same names and parents, physics' ``seat`` joint included),
animated by their local rotations, and a tip joint per stick (the BVH's End Site); the links' shapes (a box along
each body segment, a rod per stick) are one skinned mesh bound weight 1 to their link's joint. A small numpy glTF
evaluator (node TRS, animation keys, linear blend skinning) places the skinned vertices, which must move rigidly
with their link's pose, and the shapes must be where the body is: a stick from its butt to its tip, a forearm from
the elbow to the wrist. The file faces as glTF 2.0 says an asset does: the drummer looks along +z, y up.
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
from services.graphics.export.gltf import (
    ROOT_ROTATION,
    STICK_BEAD_RADIUS_M,
    STICK_DIAMETER_M,
    STICK_GRIP_M,
    STICK_TIP_M,
    _box,
)
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


def link_vertices(gltf: pygltflib.GLTF2, key: int) -> dict[str, np.ndarray]:
    """The skinned vertices at key ``key`` by the name of the joint they are bound to (metres, y up)."""
    placed = skinned_vertices(gltf, key)
    skin = gltf.skins[0]
    mesh = gltf.meshes[next(n.mesh for n in gltf.nodes if n.skin is not None)]
    joints = np.concatenate([accessor(gltf, p.attributes.JOINTS_0)[:, 0] for p in mesh.primitives]).astype(int)
    return {gltf.nodes[skin.joints[j]].name: placed[joints == j] for j in np.unique(joints)}


def in_link_frame(sequence: PoseSequence, key: int, name: str, points: np.ndarray) -> np.ndarray:
    """``points`` (N, 3; the file's world: y up) in link ``name``'s frame at pose ``key`` (Batteur's axes, z up)."""
    pose = sequence.values[key, sequence.names.index(name)]
    world = Rotation.from_quat(ROOT_ROTATION).inv().apply(points)
    return Rotation.from_quat(normalize_quats(pose[3:])).inv().apply(world - pose[:3])


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
    tips = {"left_stick_tip": "left_stick", "right_stick_tip": "right_stick"}  # the BVH's End Sites of the sticks
    assert gltf_tree(gltf) == want | tips
    skin = gltf.skins[0]
    assert [gltf.nodes[j].name for j in skin.joints] == list(want) + list(tips)  # the BVH's order: parents first
    assert info.joints == len(want) + 2
    # the root joint (the pelvis) hangs from the file's root node (z up -> y up), as the link nodes do
    root = next(n for n in gltf.nodes if n.name == "batteur")
    assert skin.joints[0] in root.children and gltf.nodes[skin.skeleton].name == "pelvis"
    # every joint turns: its rotation is animated (the pelvis' translation too); the tips stay on their stick
    animated = {(gltf.nodes[c.target.node].name, c.target.path) for c in gltf.animations[0].channels}
    assert all((name, "rotation") in animated for name in want) and ("pelvis", "translation") in animated
    assert not any(name in tips for name, _ in animated)


@pytest.mark.parametrize("source", ["physics", "synthetic"])
def test_skinned_vertices_move_with_their_links(source: str, physics_poses: PoseSequence, tmp_path: Path) -> None:
    """At 3 keys every vertex of the skinned body is within 1e-5 m of where its link's pose at that key puts the
    point it is on (its place in the link's frame taken at the first key), for physics' character (seat joint,
    rocked pelvis) and another skeleton; each vertex has one joint, weight 1."""
    seq = physics_poses if source == "physics" else synthetic_performance(duration=1.5, rate_hz=60.0)[0]
    write_gltf(seq, tmp_path / "p.glb", kit=load_kit("default"), link_size=LINK_SIZE_M)
    gltf = load(tmp_path / "p.glb")
    assert not any(n.mesh is not None and n.name.endswith("_mesh") for n in gltf.nodes)  # no rigid body box left
    first = link_vertices(gltf, 0)
    assert set(first) == {n for n in seq.names if not n.startswith("kit.")}  # every body link is drawn
    local = {name: in_link_frame(seq, 0, name, v) for name, v in first.items()}
    root = Rotation.from_quat(ROOT_ROTATION)
    for key in FRAMES:
        for name, got in link_vertices(gltf, key).items():
            pose = seq.values[key, seq.names.index(name)]
            want = root.apply(Rotation.from_quat(normalize_quats(pose[3:])).apply(local[name]) + pose[:3])
            assert np.abs(got - want).max() < 1e-5, (key, name)  # metres
    for primitive in gltf.meshes[next(n.mesh for n in gltf.nodes if n.skin is not None)].primitives:
        weights = accessor(gltf, primitive.attributes.WEIGHTS_0)
        assert np.all(weights[:, 0] == 1.0) and np.all(weights[:, 1:] == 0.0)


def test_a_stick_is_a_rod_from_its_butt_to_its_tip_joint(physics_poses: PoseSequence, tmp_path: Path) -> None:
    """Each stick's tip is a joint (``<stick>_tip``, its child, at physics' bead centre 26.95 cm along the stick's
    +y), so an importer gives the stick bone its length (the BVH's End Site); the stick is drawn as a rod along
    +y from the butt (13 cm behind the fulcrum) past the bead, 40.6 cm, about 1.5 cm across (it was a 2.5 cm cube
    at the fulcrum)."""
    write_gltf(physics_poses, tmp_path / "p.glb", kit=load_kit("default"))
    gltf = load(tmp_path / "p.glb")
    names = [n.name for n in gltf.nodes]
    shapes = link_vertices(gltf, 0)
    for side in ("left", "right"):
        stick, tip = names.index(f"{side}_stick"), names.index(f"{side}_stick_tip")
        assert tip in gltf.nodes[stick].children and tip in gltf.skins[0].joints
        np.testing.assert_allclose(gltf.nodes[tip].translation, [0.0, 0.2695, 0.0], atol=1e-7)
        for key in FRAMES:  # the tip joint is where the stick's pose puts physics' tip
            pose = physics_poses.values[key, physics_poses.names.index(f"{side}_stick")]
            bead = Rotation.from_quat(normalize_quats(pose[3:])).apply([0.0, 0.2695, 0.0]) + pose[:3]
            placed = global_transforms(gltf, key)[tip][:3, 3]
            np.testing.assert_allclose(placed, Rotation.from_quat(ROOT_ROTATION).apply(bead), atol=1e-5)
        rod = in_link_frame(physics_poses, 0, f"{side}_stick", shapes[f"{side}_stick"])
        assert rod[:, 1].min() == pytest.approx(-0.13, abs=1e-5) and rod[:, 1].max() == pytest.approx(0.276, abs=1e-5)
        across = np.linalg.norm(rod[:, [0, 2]], axis=1)
        assert 0.007 < across.max() <= 0.0075  # metres: the rod's radius, physics' 7.3 mm


def test_the_sticks_drawn_are_physics_sticks() -> None:
    """The export's stick sizes are physics' 5A stick's (graphics cannot import physics: they are copied)."""
    from services.physics.sticks import StickSpec

    spec = StickSpec()
    assert STICK_TIP_M == pytest.approx(spec.tip_offset)
    assert (STICK_GRIP_M, STICK_BEAD_RADIUS_M) == (spec.grip_m, spec.tip_radius_m)
    assert STICK_DIAMETER_M == pytest.approx(2 * spec.radius_m)


def test_body_links_are_boxes_along_their_segments(physics_poses: PoseSequence, tmp_path: Path) -> None:
    """A body link's box runs from its joint to its child joint (a forearm from the elbow to the wrist, a thigh from
    the hip to the knee), link_size across; a leaf given an End Site (a foot's ball) runs to it; a leaf without one
    (the head) stays a cube."""
    foot_ball = np.array([0.0, 0.14156, -0.080414])
    write_gltf(physics_poses, tmp_path / "p.glb", kit=load_kit("default"), link_size=LINK_SIZE_M,
               end_sites={"right_foot": foot_ball})
    gltf = load(tmp_path / "p.glb")
    shapes = link_vertices(gltf, 0)
    names = physics_poses.names
    pose = physics_poses.values[0]

    def child_offset(link: str, child: str) -> np.ndarray:
        """``child``'s origin in ``link``'s frame, metres."""
        rot = Rotation.from_quat(normalize_quats(pose[names.index(link), 3:]))
        return rot.inv().apply(pose[names.index(child), :3] - pose[names.index(link), :3])

    for link, end in (("right_forearm", child_offset("right_forearm", "right_hand")),
                      ("left_thigh", child_offset("left_thigh", "left_shank")), ("right_foot", foot_ball)):
        box = in_link_frame(physics_poses, 0, link, shapes[link])
        length = float(np.linalg.norm(end))
        along = box @ (end / length)
        assert along.min() == pytest.approx(0.0, abs=1e-6) and along.max() == pytest.approx(length, abs=1e-6), link
        across = box - np.outer(along, end / length)
        assert np.linalg.norm(across, axis=1).max() == pytest.approx(LINK_SIZE_M / np.sqrt(2), abs=1e-6), link
    head = in_link_frame(physics_poses, 0, "head", shapes["head"])
    np.testing.assert_allclose(np.ptp(head, axis=0), [2.5 * LINK_SIZE_M] * 3, atol=1e-6)


def test_the_unit_box_is_a_cube_with_outward_faces() -> None:
    """Edge 1 centred on the origin (it spanned 2 x 2 x 1: the x and y faces took their normal as a tangent),
    each triangle counter-clockwise seen from outside, along its face's normal."""
    pos, nor, idx = _box()
    np.testing.assert_array_equal(pos.min(axis=0), [-0.5] * 3)
    np.testing.assert_array_equal(pos.max(axis=0), [0.5] * 3)
    triangles = pos[idx.reshape(-1, 3)]
    normals = nor[idx.reshape(-1, 3)[:, 0]]
    twice_area = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    assert np.allclose(twice_area, normals)  # each triangle half its unit face, wound about its outward normal
    assert np.all(np.einsum("ij,ij->i", triangles.mean(axis=1), normals) > 0)


def test_the_drummer_faces_plus_z(physics_poses: PoseSequence, tmp_path: Path) -> None:
    """glTF 2.0: "the front of a glTF asset faces +Z", y up (Blender and three.js import it so): the kit is in
    front of the drummer at +z, his head above his pelvis along +y, his left (the left hip) at +x (the file had
    him face -z: the default front view showed his back)."""
    write_gltf(physics_poses, tmp_path / "p.glb", kit=load_kit("default"))
    gltf = load(tmp_path / "p.glb")
    names = [n.name for n in gltf.nodes]
    placed = global_transforms(gltf, 0)

    def at(name: str) -> np.ndarray:
        return placed[names.index(name)][:3, 3]

    pelvis = at("pelvis")
    for drum in ("kit_snare", "kit_kick", "kit_ride", "kit_hightom"):
        assert at(drum)[2] - pelvis[2] > 0.2, drum  # metres in front
    assert at("head")[1] - pelvis[1] > 0.5
    assert at("left_thigh")[0] - at("right_thigh")[0] > 0.15  # the hips' width


def test_the_skinned_file_passes_the_khronos_validator(physics_poses: PoseSequence, tmp_path: Path) -> None:
    for suffix in (".glb", ".gltf"):
        path = tmp_path / f"p{suffix}"
        write_gltf(physics_poses, path, kit=load_kit("default"))
        report = validate(path)
        assert (report["numErrors"], report["numWarnings"]) == (0, 0), report["messages"]
        assert report["info"]["hasSkins"] is True
        assert report["returncode"] == 0
