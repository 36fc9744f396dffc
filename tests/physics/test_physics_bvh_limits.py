"""Joint limits from any BVH: its motion read onto our joints whatever its names, axes and rest pose."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from common.gesture.bvh import BvhError
from services.physics.bvh_motion import bvh_segment_lengths, load_bvh_clip
from services.physics.limits import default_limits, limits_from_clips, load_clip
from services.physics.mocap import MotionClip, load_deepmimic

FILE_FROM_OURS = np.array([[-1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]])
"""Our axes (x right, y forward, z up) -> a CMU-like file's: y up, facing +z, the performer's right along -x."""

T_POSE = {"left": Rotation.from_euler("y", 90, degrees=True), "right": Rotation.from_euler("y", -90, degrees=True)}
"""Turns an arm hanging down (our zero pose) out to the side, as the file's T-pose holds it."""

Row = tuple[str, str | None, tuple[float, float, float], str | None]
"""A joint of a test file: name, parent, offset in our axes (cm), the link of ours it stands for (None: a joint
ours fold into the next one)."""

CMU: list[Row] = [
    ("Hips", None, (0, 0, 95), "pelvis"), ("LowerBack", "Hips", (0, 0, 10), "abdomen"),
    ("Spine", "LowerBack", (0, 0, 10), None), ("Spine1", "Spine", (0, 0, 10), "thorax"),
    ("Neck", "Spine1", (0, 0, 20), "neck"), ("Head", "Neck", (0, 0, 8), "head"),
    *[row for side, x in (("Left", -1.0), ("Right", 1.0)) for row in (
        (f"{side}Shoulder", "Spine1", (3 * x, 0, 18), f"{side.lower()}_clavicle"),
        (f"{side}Arm", f"{side}Shoulder", (15 * x, 0, 0), f"{side.lower()}_upper_arm"),
        (f"{side}ForeArm", f"{side}Arm", (28 * x, 0, 0), f"{side.lower()}_forearm"),
        (f"{side}Hand", f"{side}ForeArm", (25 * x, 0, 0), f"{side.lower()}_hand"),
        (f"{side}UpLeg", "Hips", (9 * x, 0, -5), f"{side.lower()}_thigh"),
        (f"{side}Leg", f"{side}UpLeg", (0, 0, -42), f"{side.lower()}_shank"),
        (f"{side}Foot", f"{side}Leg", (0, 0, -42), f"{side.lower()}_foot"),
        (f"{side}ToeBase", f"{side}Foot", (0, 12, -6), None))],
]
"""CMU's names (its clavicle is LeftShoulder), a Spine joint between LowerBack and Spine1."""

BIOVISION: list[Row] = [
    ("Hips", None, (0, 0, 95), "pelvis"), ("Chest", "Hips", (0, 0, 25), "thorax"),
    ("Neck", "Chest", (0, 0, 25), "neck"), ("Head", "Neck", (0, 0, 8), "head"),
    *[row for side, x in (("Left", -1.0), ("Right", 1.0)) for row in (
        (f"{side}Collar", "Chest", (3 * x, 0, 20), f"{side.lower()}_clavicle"),
        (f"{side}Shoulder", f"{side}Collar", (15 * x, 0, 0), f"{side.lower()}_upper_arm"),
        (f"{side}Elbow", f"{side}Shoulder", (28 * x, 0, 0), f"{side.lower()}_forearm"),
        (f"{side}Wrist", f"{side}Elbow", (25 * x, 0, 0), f"{side.lower()}_hand"),
        (f"{side}Hip", "Hips", (9 * x, 0, -5), f"{side.lower()}_thigh"),
        (f"{side}Knee", f"{side}Hip", (0, 0, -42), f"{side.lower()}_shank"),
        (f"{side}Ankle", f"{side}Knee", (0, 0, -42), f"{side.lower()}_foot"))],
]
"""Biovision's names (its LeftShoulder is the upper arm, beside LeftCollar), one Chest for our two spine joints."""
_PARENT_LINK = {"abdomen": ("pelvis", "lumbar"), "thorax": ("abdomen", "thoracic"), "neck": ("thorax", "neck"),
                "head": ("neck", "head"),
                **{f"{s}_{k}": (p.format(s=s), j.format(s=s)) for s in ("left", "right") for k, p, j in (
                    ("clavicle", "thorax", "{s}_clavicle"), ("upper_arm", "{s}_clavicle", "{s}_shoulder"),
                    ("forearm", "{s}_upper_arm", "{s}_elbow"), ("hand", "{s}_forearm", "{s}_wrist"),
                    ("thigh", "pelvis", "{s}_hip"), ("shank", "{s}_thigh", "{s}_knee"),
                    ("foot", "{s}_shank", "{s}_ankle"))}}


def write_bvh_of(clip: MotionClip, path: Path, skeleton: list[Row]) -> None:
    """The clip as a BVH of ``skeleton`` (its joint names), y up, facing +z, centimetres, a T-pose at rest, rotation
    channels in Z X Y order, the pelvis turning slowly (the heading is no joint's business)."""
    frames = len(clip.times)
    c = Rotation.from_matrix(FILE_FROM_OURS.T)  # file vectors -> ours, as a rotation
    links: dict[str, Rotation] = {"pelvis": Rotation.from_euler("z", np.linspace(0, 1.5, frames)[:, None])}
    for link, (parent, joint) in _PARENT_LINK.items():
        links[link] = links[parent] * clip.rotations.get(joint, Rotation.identity(frames))
    world: dict[str, Rotation] = {}
    for name, parent, _, link in skeleton:
        if link is None:
            world[name] = world[str(parent)]  # a joint of the file's that ours fold into the next one
        else:
            arm = link.endswith(("upper_arm", "forearm", "hand"))
            align = T_POSE[link.split("_")[0]] if arm else Rotation.identity()
            world[name] = c.inv() * links[link] * align.inv() * c  # our link's frame O = C W C^T A

    lines = ["HIERARCHY"]

    def block(name: str, parent: str | None, offset: tuple[float, float, float], d: int) -> None:
        pad = "  " * d
        lines.append(f"{pad}{'ROOT' if parent is None else 'JOINT'} {name}")
        lines.append(f"{pad}{{")
        lines.append(f"{pad}  OFFSET {' '.join(f'{v:.6f}' for v in FILE_FROM_OURS @ np.array(offset, float))}")
        position = "6 Xposition Yposition Zposition" if parent is None else "3"
        lines.append(f"{pad}  CHANNELS {position} Zrotation Xrotation Yrotation")
        children = [row for row in skeleton if row[1] == name]
        for child, _, child_offset, _ in children:
            block(child, name, child_offset, d + 1)
        if not children:
            lines.extend([f"{pad}  End Site", f"{pad}  {{", f"{pad}    OFFSET 0 0 0", f"{pad}  }}"])
        lines.append(f"{pad}}}")

    block(skeleton[0][0], None, skeleton[0][2], 0)
    rows = []
    for f in range(frames):  # values in the order the blocks were written: depth first, as the skeleton lists
        values: list[float] = []
        for name, parent, offset, _ in _depth_first(skeleton):
            local = world[name][f] if parent is None else world[parent][f].inv() * world[name][f]
            if parent is None:
                values += list(FILE_FROM_OURS @ np.array(offset, float))
            values += list(local.as_euler("ZXY", degrees=True))
        rows.append(" ".join(f"{v:.9f}" for v in values))
    lines += ["MOTION", f"Frames: {frames}", f"Frame Time: {clip.times[1] - clip.times[0]:.9f}", *rows]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def _depth_first(skeleton: list[Row]) -> list[Row]:
    """The skeleton in the file's order (each joint's block holds its children's)."""
    out: list[Row] = []

    def visit(row: Row) -> None:
        out.append(row)
        for child in skeleton:
            if child[1] == row[0]:
                visit(child)

    visit(skeleton[0])
    return out


@pytest.mark.parametrize("skeleton", [CMU, BIOVISION], ids=["cmu", "biovision"])
def test_a_t_pose_bvh_gives_back_the_clips_joint_rotations(tmp_path: Path, skeleton: list[Row]) -> None:
    """A DeepMimic clip written as a BVH of another convention (CMU's or Biovision's names, y up, facing +z,
    a T-pose at rest, the hips turning; CMU's Spine between two of ours, Biovision's one Chest for two) reads
    back as the same rotations of our joints."""
    clip = load_deepmimic("punch")
    path = tmp_path / "punch.bvh"
    write_bvh_of(clip, path, skeleton)
    read = load_bvh_clip(path)
    assert read.name == "punch" and read.rate_hz == pytest.approx(clip.rate_hz)
    for joint, rotation in clip.rotations.items():
        error = (read.rotations[joint].inv() * rotation).magnitude()
        assert error.max() < 1e-6, joint
    for joint in ("left_clavicle", "right_wrist"):  # in the file, never turned
        assert read.rotations[joint].magnitude().max() < 1e-6


def test_limits_from_a_bvh_contain_at_least_99_percent_of_its_frames(tmp_path: Path) -> None:
    path = tmp_path / "dance_a.bvh"
    write_bvh_of(load_deepmimic("dance_a"), path, CMU)
    clip = load_clip(path)
    limits = limits_from_clips([clip])
    assert limits.quaternion
    inside = np.ones(len(clip.times), dtype=bool)
    for joint, qlim in limits.quaternion.items():
        inside &= qlim.contains(clip.quaternions(joint))
    assert inside.mean() >= 0.99
    for joint in clip.rotations:
        if limits.sources[joint] == "mocap":
            assert limits.euler[joint].contains(clip.euler(joint)).mean() >= 0.99
    # the same limits as from the DeepMimic clip itself, where the file drives a joint
    again = default_limits(["dance_a"])
    for joint in ("left_elbow", "right_shoulder", "lumbar", "left_knee"):
        np.testing.assert_allclose(limits.euler[joint].lower, again.euler[joint].lower, atol=1e-6)
        np.testing.assert_allclose(limits.euler[joint].upper, again.euler[joint].upper, atol=1e-6)


@pytest.mark.parametrize(("text", "says"), [
    ("HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 3 Zrotation Xrotation Yrotation\n JOINT Tail\n {\n"
     "  OFFSET 0 1 0\n  CHANNELS 3 Zrotation Xrotation Yrotation\n  End Site\n  {\n   OFFSET 0 1 0\n  }\n }\n}\n"
     "MOTION\nFrames: 2\nFrame Time: 0.03\n0 0 0 0 0 0\n0 0 0 5 0 0\n", "cannot tell which way is up"),
    ("HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 3 Zrotation Xrotation Yrotation\n}\n"
     "MOTION\nFrames: 2\nFrame Time: 0.03\n0 0 0\nnan 0 0\n",
     "line 11: motion frame 2 of 2 .frames counted from 1., channel 1 .Hips Zrotation. holds a value that is not"),
    ("HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 3 Zrotation Xrotation Yrotation\n}\n"
     "MOTION\nFrames: 1\nFrame Time: 0.03\n0 0 0\n", "at least two"),
])
def test_a_bvh_that_cannot_give_limits_is_named_with_the_problem(tmp_path: Path, text: str, says: str) -> None:
    path = tmp_path / "odd.bvh"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(BvhError, match=f"odd.bvh.*{says}"):
        load_clip(path)
    with pytest.raises(FileNotFoundError, match="no BVH file"):
        load_clip(tmp_path / "missing.bvh")


def test_our_own_bvh_export_reads_back_as_the_simulated_joint_angles(tmp_path: Path) -> None:
    """The drummer's motion as `batteur render` writes it (performance.bvh: our link names, y up, facing -z,
    the zero pose at rest) reads back as the joint angles the simulation had (the trunk's joints and the arms';
    the hips are read against the pelvis, the simulation's against the throne). Left and right are told by
    the shoulders: the legs' offsets from the pelvis change as it rocks, and taken from them they tilted every
    joint by up to 0.7 degrees."""
    from common.character import DOF_NAMES
    from common.messages import Pose, Skeleton
    from services.graphics.export.bvh import write_bvh
    from services.graphics.recorder import PerformanceRecorder
    from services.graphics.sequence import PoseSequence
    from services.physics.core import PhysicsCore
    from services.physics.drummer import DrummerScene

    core = PhysicsCore(scene="drummer", pose_rate_hz=50.0)
    scene = core.scene
    assert isinstance(scene, DrummerScene)
    scene.add_cartesian("right_hand", 0.4, scene.rest_targets["right_hand"] + [0.1, 0.1, 0.15], np.zeros(3), 0.0)
    recorder = PerformanceRecorder()
    angles: dict[float, np.ndarray] = {}
    for k in range(1, 601):
        for out in core.step(k / 1000):
            if isinstance(out.message, (Pose, Skeleton)):
                recorder.record(out.message)
                if isinstance(out.message, Pose):
                    angles[out.message.time] = scene.body.state()[0].copy()
    core.close()
    every = recorder.sequence()  # the first pose at the first step, then every 20 ms: keep the even ones,
    poses = PoseSequence(every.names, every.times[1:], every.values[1:])  # which the BVH's frames fall on
    write_bvh(poses, tmp_path / "performance.bvh")
    clip = load_bvh_clip(tmp_path / "performance.bvh")
    assert len(clip.times) >= 25  # resampled at the poses' own rate: frame k is the pose k (the last may go)
    q = np.array([angles[t] for t in poses.times[:len(clip.times)]])
    for joint in ("lumbar", "thoracic", "neck", "head", "right_clavicle", "right_shoulder", "right_elbow",
                  "right_wrist", "left_elbow", "left_knee", "right_ankle"):
        k = DOF_NAMES.index(f"{joint}_x")
        simulated = Rotation.from_euler("XYZ", q[:, k:k + 3])
        error = (clip.rotations[joint].inv() * simulated).magnitude()
        assert error.max() < 1e-4, joint  # radians; OSC's 32-bit floats and the file's decimals
    arm = clip.rotations["right_shoulder"]
    assert (arm[0].inv() * arm[-1]).magnitude() > 0.05  # radians (0.064): the arm moved, not only rest poses


def test_a_skeletons_proportions_are_read_from_its_rest_pose(tmp_path: Path) -> None:
    """The shoulders' height above the hips (joint centres' midpoints), the neck, the shoulder and hip widths and
    the limbs, in both conventions' names."""
    for skeleton, shoulder_height in ((CMU, 0.53), (BIOVISION, 0.50)):
        path = tmp_path / "punch.bvh"
        write_bvh_of(load_deepmimic("punch"), path, skeleton)
        assert bvh_segment_lengths(path) == pytest.approx({
            "upper_arm": 0.28, "forearm": 0.25, "thigh": 0.42, "shank": 0.42, "neck": 0.08,
            "shoulder_height": shoulder_height, "shoulder_width": 0.36, "hip_width": 0.18})


def test_a_drummer_built_from_a_bvh_skeleton_has_its_proportions(tmp_path: Path) -> None:
    """`skeleton_bvh`: the joint centres of the body PyBullet simulates are where the file's are (the rest of the
    body keeps de Leva's table); and the drummer's own export reads back as the body it came from."""
    from services.physics.anthropometry import SHOULDER_BELOW_NECK
    from services.physics.core import PhysicsCore
    from services.physics.drummer import DrummerScene

    skeleton = [(name, parent, (offset[0], offset[1], offset[2] + 12) if name in ("Neck", "LeftShoulder",
                 "RightShoulder") else offset, link) for name, parent, offset, link in CMU]
    # shoulders 0.65 m above the hips, the table's 0.57 m at 1.75 m
    path = tmp_path / "tall.bvh"
    write_bvh_of(load_deepmimic("punch"), path, skeleton)
    core = PhysicsCore(scene="drummer", skeleton_bvh=str(path), pose_rate_hz=50.0)
    scene = core.scene
    assert isinstance(scene, DrummerScene)
    body = scene.body
    # measured on the body in its zero pose, frames aligned with the world: x right, z up
    for part in body.parts:
        for j in part.movable:
            body.world.client.resetJointState(part.id, j, 0.0, 0.0)

    def centre(joint: str) -> np.ndarray:
        return np.asarray(body.link_pose(body.joint_index[f"{joint}_x"])[0])

    hips = (centre("left_hip") + centre("right_hip")) / 2
    shoulders = (centre("left_shoulder") + centre("right_shoulder")) / 2
    assert shoulders[2] - hips[2] == pytest.approx(0.65, abs=1e-6)
    assert np.linalg.norm(centre("left_shoulder") - centre("right_shoulder")) == pytest.approx(0.36, abs=1e-6)
    assert np.linalg.norm(centre("left_hip") - centre("right_hip")) == pytest.approx(0.18, abs=1e-6)
    assert np.linalg.norm(centre("head") - centre("neck")) == pytest.approx(0.08, abs=1e-6)
    core.close()

    # the default drummer's export: its own proportions come back
    from common.messages import Pose, Skeleton
    from services.graphics.export.bvh import write_bvh
    from services.graphics.recorder import PerformanceRecorder

    core = PhysicsCore(scene="drummer", pose_rate_hz=50.0)
    scene = core.scene
    assert isinstance(scene, DrummerScene)
    recorder = PerformanceRecorder()
    for k in range(1, 61):
        for out in core.step(k / 1000):
            if isinstance(out.message, (Pose, Skeleton)):
                recorder.record(out.message)
    core.close()
    write_bvh(recorder.sequence(), tmp_path / "performance.bvh")
    seg = scene.anthro.segments
    assert bvh_segment_lengths(tmp_path / "performance.bvh") == pytest.approx({
        **{kind: seg[kind].length_m for kind in ("upper_arm", "forearm", "thigh", "shank", "neck")},
        "shoulder_height": seg["pelvis"].length_m + seg["abdomen"].length_m + seg["thorax"].length_m
        - SHOULDER_BELOW_NECK * scene.anthro.scale,
        "shoulder_width": scene.anthro.shoulder_width_m, "hip_width": scene.anthro.hip_width_m}, abs=1e-4)


def test_a_drummer_takes_its_limits_and_arm_lengths_from_a_bvh(tmp_path: Path) -> None:
    """`limits_from` and `skeleton_bvh`: the drummer's joint limits come from the file's motion (grown only
    where they do not hold the playing posture), PyBullet enforces them, and its arms and legs are the file's."""
    from common.character import DOF_NAMES
    from common.messages import Contact
    from common.messages.physics import JointTarget
    from services.physics.core import PhysicsCore
    from services.physics.drummer import DrummerScene

    path = tmp_path / "punch.bvh"
    write_bvh_of(load_deepmimic("punch"), path, CMU)
    core = PhysicsCore(scene="drummer", limits_from=(str(path),), skeleton_bvh=str(path))
    scene = core.scene
    assert isinstance(scene, DrummerScene)
    assert scene.anthro.segments["upper_arm"].length_m == pytest.approx(0.28)  # the file's 28 cm
    assert scene.anthro.segments["forearm"].length_m == pytest.approx(0.25)
    assert scene.anthro.segments["thigh"].length_m == pytest.approx(0.42)
    limits = scene.limits
    assert limits.sources["right_elbow"].startswith("mocap")
    assert limits.sources["left_clavicle"] == "mocap+anatomical"  # never turned in the file: anatomical range
    punch = limits_from_clips([load_clip(path)], symmetric=True)  # both sides' common range, as the drummer's
    k = DOF_NAMES.index("right_elbow_x")
    assert scene.body.upper[k] == pytest.approx(punch.euler["right_elbow"].upper[0])  # the punch's elbow range
    assert scene.body.upper[k] < default_limits().euler["right_elbow"].upper[0] - 0.05  # not all DeepMimic clips'
    # the playing posture is inside: holding it touches nothing and meets no limit
    contacts = sum(isinstance(o.message, Contact) for i in range(1, 301) for o in core.step(i / 1000))
    assert contacts == 0 and scene.controller.limit_violations == 0
    # the drummer refuses a target beyond the file's elbow range, and PyBullet stops the joint there
    q = scene.body.state()[0].copy()
    q[k] = scene.body.upper[k] + 0.2
    core.handle(JointTarget(time=0.4, values=(*q, *np.zeros(57))), 0.3, "test")
    assert core.rejected["JointTarget"] == 1
    body = scene.body
    part, joint = body.link_ref[body.dof_list[k]]
    body.world.client.resetJointState(part, joint, float(body.upper[k]) - 0.01, 8.0)  # swinging out fast
    furthest = 0.0
    for i in range(301, 341):
        core.step(i / 1000)
        furthest = max(furthest, float(body.state()[0][k]))
    assert furthest < body.upper[k] + 0.01  # radians; 2.506 (DeepMimic's stop) without the file's limit
    core.close()
