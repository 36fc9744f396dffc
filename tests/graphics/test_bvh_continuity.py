"""BVH rotation channels are continuous: a forearm twisting past 180 degrees read 179 then -179 (a 358-degree jump
between frames; the demo's performance.bvh had 51 such jumps in its forearms), which a tool interpolating the
channels (retiming, motion blur, Maya's or MotionBuilder's curves before an Euler filter) turns into a full spin.
The file's forward kinematics is unchanged."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from services.graphics.export import write_bvh
from services.graphics.export.bvh import BvhStream
from services.graphics.sequence import PoseSequence

NAMES = ["pelvis", "right_upper_arm", "right_forearm", "right_hand"]


def _twisting(frames: int = 90) -> PoseSequence:
    """The forearm (and the hand with it) turning about the arm, from 150 to 330 degrees; the arm hangs down."""
    times = np.arange(frames) / 60.0
    values = np.zeros((frames, len(NAMES), 7))
    values[:, :, 6] = 1.0
    values[:, 0, :3] = [0.0, 0.0, 1.0]
    values[:, 1, :3] = [0.2, 0.0, 1.4]
    values[:, 2, :3] = [0.2, 0.0, 1.1]
    values[:, 3, :3] = [0.2, 0.0, 0.85]
    twist = Rotation.from_euler("z", np.linspace(150, 330, frames)[:, None], degrees=True).as_quat()
    values[:, 2, 3:] = twist
    values[:, 3, 3:] = twist
    return PoseSequence(list(NAMES), times, values)


def _motion(path: Path) -> np.ndarray:
    lines = path.read_text().splitlines()
    start = lines.index("MOTION") + 3
    return np.array([[float(v) for v in row.split()] for row in lines[start:]])


def test_a_twist_past_180_degrees_has_no_jump_of_a_turn(tmp_path: Path) -> None:
    seq = _twisting()
    info = write_bvh(seq, tmp_path / "twist.bvh", rate_hz=60.0)
    motion = _motion(tmp_path / "twist.bvh")
    steps = np.abs(np.diff(motion[:, 3:], axis=0))  # rotation channels (the root's position first)
    assert steps.max() < 10, f"a channel jumps by {steps.max():.1f} degrees between frames"
    assert info.max_error < 1e-9  # the same rotations


def test_the_stream_gives_the_same_continuous_bytes_in_chunks(tmp_path: Path) -> None:
    seq = _twisting()
    write_bvh(seq, tmp_path / "whole.bvh", rate_hz=60.0)
    stream = BvhStream(tmp_path / "stream.bvh", 60.0, chunk_frames=7)  # chunk edges inside the twist
    stream.restart(list(seq.names))
    for t, v in zip(seq.times, seq.values, strict=True):
        stream.add(float(t), v)
    stream.finish()
    assert (tmp_path / "stream.bvh").read_bytes() == (tmp_path / "whole.bvh").read_bytes()
