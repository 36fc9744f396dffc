"""performance.bvh puts the legs where physics has them when the pelvis rocks.

Physics' thighs turn on hip mounts fixed on the throne, not on the pelvis (common/character.py ``HIP_MOUNTS``): the
pelvis rocking on the seat does not swing them. The file hung the thighs from the pelvis with the first frame's
offsets, so a rocked pelvis swung the legs with it (up to 9.4 cm on the demo's fill); it now has a ``seat`` joint,
the pelvis' child turned back to the throne's frame, that carries the thighs at the hip mounts.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from common.gesture.bvh import forward_kinematics, read_bvh
from services.graphics.export import write_bvh
from services.graphics.export.bvh import DEFAULT_FACING, Y_UP, BvhStream
from services.graphics.sequence import PoseSequence
from services.physics.bvh_motion import bvh_segment_lengths, map_segments
from tests.graphics.physics_poses import posed_frames

ROCKS = ((0.0, 0.0, 0.0), (10.0, 10.0, 10.0), (-10.0, 10.0, -10.0), (10.0, -10.0, 10.0))
"""The pelvis' seat angles (x, y, z degrees) of the frames: at rest first (the file's offsets), then rocked."""


@pytest.fixture(scope="module")
def physics_poses() -> PoseSequence:
    """Physics' own link frames (its Pose message) with the pelvis rocked as ``ROCKS`` and the legs and an arm bent
    (the same in every frame: only the pelvis moves)."""
    bent = {"left_hip": (70.0, -8.0, 5.0), "right_hip": (85.0, 6.0, -10.0), "left_knee": (-80.0, 0.0, 0.0),
            "right_ankle": (15.0, 0.0, 5.0), "right_elbow": (60.0, 0.0, 20.0)}
    return posed_frames([{**bent, "seat": rock} for rock in ROCKS])


def test_a_rocked_pelvis_leaves_the_legs_where_physics_has_them(physics_poses: PoseSequence, tmp_path: Path) -> None:
    seq = physics_poses
    thighs = [seq.names.index(f"{side}_thigh") for side in ("left", "right")]
    assert np.allclose(seq.values[1:, thighs, :3], seq.values[0, thighs, :3], atol=1e-9)  # physics: the hips stay
    path = tmp_path / "rocked.bvh"
    info = write_bvh(seq, path, rate_hz=60.0)
    assert info.max_error < 1e-6  # metres: the writer's own forward kinematics, before rounding (PyBullet: 2e-7)
    placed = forward_kinematics(read_bvh(path))  # our reader, from the file's 6 decimals
    body = [name for name in info.joints if name in seq.names]  # not the throne joint: no link
    assert {"left_thigh", "right_foot", "right_stick", "head"} <= set(body)
    for frame in range(len(ROCKS)):
        for name in body:
            physics = Y_UP[DEFAULT_FACING] @ seq.values[frame, seq.names.index(name), :3]
            assert np.linalg.norm(placed[name][frame] - physics) < 1e-5, (frame, name)  # metres


def test_the_streamed_file_is_the_same(physics_poses: PoseSequence, tmp_path: Path) -> None:
    write_bvh(physics_poses, tmp_path / "whole.bvh", rate_hz=60.0)
    stream = BvhStream(tmp_path / "streamed.bvh", 60.0, chunk_frames=2)
    stream.restart(list(physics_poses.names))
    for t, values in zip(physics_poses.times, physics_poses.values, strict=True):
        stream.add(float(t), values)
    stream.finish()
    assert (tmp_path / "streamed.bvh").read_bytes() == (tmp_path / "whole.bvh").read_bytes()


def test_readers_find_the_legs_under_the_hips(physics_poses: PoseSequence, tmp_path: Path) -> None:
    """The thighs stay the pelvis' descendants (the throne joint between them): a reader looking for the legs
    under the hips finds them, the hips as wide apart as physics' hip mounts."""
    path = tmp_path / "rocked.bvh"
    write_bvh(physics_poses, path, rate_hz=60.0)
    segments = map_segments(read_bvh(path))
    assert {"left_thigh", "right_thigh", "left_foot", "right_foot"} <= set(segments)
    names = list(physics_poses.names)
    left, right = (physics_poses.values[0, names.index(f"{side}_thigh"), :3] for side in ("left", "right"))
    assert bvh_segment_lengths(path)["hip_width"] == pytest.approx(float(np.linalg.norm(right - left)), abs=1e-6)
