"""performance.bvh for animators, on physics' character (the pose editor's snapshot moved by its own forward
kinematics, so the input is rigid):

- the last bones' End Sites (where Blender and Maya put their tails): a stick's at its tip (it was a 1.3 cm stub 22
  degrees off the stick), a foot's at the ball of the foot (it continued the shin), the foot's scaled with the body;
- each joint's rotation channel order keeps its middle angle away from +-90 degrees: a forearm flexed past 90 degrees
  in ZXY made steps of 80-100 degrees between frames in two channels that cancelled; the orders come from the
  joints' limits, so every file has the same channels;
- the forward kinematics of the written channels is the input's, read back by bvhio and by our own reader.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from common.character import JOINTS
from common.gesture.bvh import forward_kinematics, read_bvh
from services.graphics.export import write_bvh
from services.graphics.export.bvh import DEFAULT_FACING, THRONE_JOINT, Y_UP, BvhStream
from services.graphics.poser import load_character, rest_poser
from services.graphics.sequence import PoseSequence

FRAMES = 61


def _q(edits: dict[str, tuple[float, float, float]]) -> np.ndarray:
    poser = rest_poser()
    q = poser.angles.copy()
    for joint, angles in edits.items():
        k = JOINTS.index(joint)
        q[3 * k:3 * k + 3] = np.radians(angles)
    return q


def _drumming(frames: int = FRAMES, scale: float = 1.0) -> PoseSequence:
    """The character flexing both elbows from 40 to 140 degrees while the forearms turn (pronation) and the wrists,
    hips and ankles move: each joint angle changes by at most 2 degrees a frame. ``scale``: the body's size."""
    poser = rest_poser()
    u = np.linspace(0.0, 1.0, frames)
    values = []
    for s in u:
        edits: dict[str, tuple[float, float, float]] = {}
        for side, sign in (("left", -1.0), ("right", 1.0)):
            edits[f"{side}_elbow"] = (40 + 100 * s, sign * 5 * np.sin(6 * s), 40 * np.sin(3 * s))
            edits[f"{side}_wrist"] = (30 * np.sin(4 * s), 10 * s, 15 * np.cos(4 * s))
            edits[f"{side}_hip"] = (70 + 30 * s, sign * 10 * s, sign * 20 * np.sin(3 * s))
            edits[f"{side}_ankle"] = (20 * np.sin(5 * s), 0.0, 10 * s)
        pose = poser.pose(_q(edits))
        pose[:, :3] *= scale
        values.append(pose)
    return PoseSequence(list(poser.names), np.arange(frames) / 60.0, np.stack(values))


def _motion(path: Path) -> np.ndarray:
    lines = path.read_text().splitlines()
    start = lines.index("MOTION") + 3
    return np.array([[float(v) for v in row.split()] for row in lines[start:]])


def _channels(path: Path) -> dict[str, str]:
    """joint -> its CHANNELS line's rotation order, e.g. ``XZY``."""
    joints: dict[str, str] = {}
    name = ""
    for line in path.read_text().split("MOTION")[0].splitlines():
        words = line.split()
        if words and words[0] in ("ROOT", "JOINT"):
            name = words[1]
        elif words and words[0] == "CHANNELS":
            joints[name] = "".join(w[0] for w in words[2:] if w.endswith("rotation"))
    return joints


@pytest.mark.parametrize("scale", [1.0, 1.2])
def test_the_stick_bone_runs_to_the_tip_and_the_foot_bone_to_the_ball_of_the_foot(tmp_path: Path,
                                                                                  scale: float) -> None:
    bvhio = pytest.importorskip("bvhio")
    seq = _drumming(scale=scale)
    path = tmp_path / "perf.bvh"
    write_bvh(seq, path, rate_hz=60.0)
    info = load_character()
    stick_tip = float(np.linalg.norm(info.effectors["right_hand"][1]))  # physics' stick: fulcrum to the bead
    ball = info.effectors["right_foot"][1]
    joints: dict[str, object] = {}
    stack = [bvhio.readAsBvh(str(path)).Root]
    while stack:
        joint = stack.pop()
        joints[joint.Name] = joint
        stack.extend(joint.Children)
    for side in ("left", "right"):
        stick, foot = joints[f"{side}_stick"], joints[f"{side}_foot"]
        # in the bone's own frame: the stick's tip along its axis (the stick's +y, +z in a file facing +z); the sticks
        # are the same for every body, the foot grows with it
        tip = Y_UP[DEFAULT_FACING] @ [0.0, stick_tip, 0.0]
        assert np.allclose(list(stick.EndSite), tip, atol=1e-6)  # type: ignore[attr-defined]
        assert np.allclose(list(foot.EndSite), Y_UP[DEFAULT_FACING] @ ball * scale, atol=1e-5)  # type: ignore[attr-defined]
    # every frame: the End Sites are where the character's stick tips and balls of the feet are (their links'
    # offsets in the stick and the foot; the foot's scaled with the body, the stick's not)
    placed = forward_kinematics(read_bvh(path))
    names = list(seq.names)
    for frame in range(0, FRAMES, 10):
        for limb, link, size in (("left_hand", "left_stick", 1.0), ("right_hand", "right_stick", 1.0),
                                 ("left_foot", "left_foot", scale), ("right_foot", "right_foot", scale)):
            row = seq.values[frame, names.index(link)]
            tip = row[:3] + Rotation.from_quat(row[3:]).apply(info.effectors[limb][1] * size)
            assert np.allclose(placed[f"{link}_end"][frame], Y_UP[DEFAULT_FACING] @ tip, atol=2e-5), (frame, limb)


def test_forearms_flexed_past_90_degrees_make_no_gimbal_steps(tmp_path: Path) -> None:
    bvhio = pytest.importorskip("bvhio")
    seq = _drumming()
    path = tmp_path / "perf.bvh"
    info = write_bvh(seq, path, rate_hz=60.0)
    motion = _motion(path)
    steps = np.abs(np.diff(motion[:, 3:], axis=0))  # rotation channels (the root's position first)
    # the joints' own angles change by at most 2 degrees a frame (ZXY: 87 degrees, the forearms')
    assert steps.max() < 2.5, f"a rotation channel steps by {steps.max():.1f} degrees between frames"
    channels = _channels(path)
    assert channels["left_forearm"] == channels["right_forearm"] == "XZY"  # the elbow's own x, y, z angles
    # the rotations are the input's: forward kinematics of the angles written (before rounding), and as bvhio reads
    # the file with each joint's own order
    assert info.max_error < 1e-9
    root = bvhio.readAsHierarchy(str(path))
    layout = root.layout()
    names = list(seq.names)
    for frame in (0, 30, 60):
        root.loadPose(frame)
        for joint, _, _ in layout:
            link = "pelvis" if joint.Name == THRONE_JOINT else joint.Name  # the throne joint: at the seat point
            want = Y_UP[DEFAULT_FACING] @ seq.values[frame, names.index(link), :3]
            assert np.allclose(list(joint.PositionWorld), want, atol=1e-4), (frame, joint.Name)


def test_the_channel_orders_come_from_the_body_not_the_performance(tmp_path: Path) -> None:
    still = _drumming(frames=2)
    still = PoseSequence(list(still.names), still.times, np.stack([still.values[0]] * 2))
    write_bvh(still, tmp_path / "still.bvh", rate_hz=60.0)
    write_bvh(_drumming(), tmp_path / "moving.bvh", rate_hz=60.0)
    orders = _channels(tmp_path / "moving.bvh")
    assert _channels(tmp_path / "still.bvh") == orders
    # mirrored joints share their order; the shoulders (abduction to 90 degrees) keep ZXY, the others are XZY
    assert all(orders[f"left_{part}"] == orders[f"right_{part}"] for part in ("upper_arm", "forearm", "thigh"))
    assert orders["left_upper_arm"] == "ZXY" and orders["pelvis"] == "XZY"


def test_the_stream_writes_the_same_character_file_in_chunks(tmp_path: Path) -> None:
    seq = _drumming()
    write_bvh(seq, tmp_path / "whole.bvh", rate_hz=60.0)
    stream = BvhStream(tmp_path / "stream.bvh", 60.0, chunk_frames=7)
    stream.restart(list(seq.names))
    for t, v in zip(seq.times, seq.values, strict=True):
        stream.add(float(t), v)
    stream.finish()
    assert (tmp_path / "stream.bvh").read_bytes() == (tmp_path / "whole.bvh").read_bytes()


def test_other_skeletons_keep_zxy() -> None:
    from services.graphics.export.bvh import rotation_orders
    from services.graphics.figure import LINK_NAMES

    assert set(rotation_orders(list(LINK_NAMES)).values()) == {"ZXY"}
