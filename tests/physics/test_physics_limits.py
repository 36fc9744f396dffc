"""Joint limits from motion capture (Euler statistics and the quaternion Algorithm 1), enforced in simulation."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from services.physics.limits import (
    euler_limits,
    limits_from_clips,
    mean_quaternion,
    quaternion_limits,
)
from services.physics.mocap import deepmimic_clip_names, load_deepmimic


def test_deepmimic_clips_load_in_our_axes() -> None:
    assert {"punch", "walk", "dance_a"} <= set(deepmimic_clip_names())
    clip = load_deepmimic("walk")
    assert clip.rate_hz == pytest.approx(30.0, rel=0.01)
    knee = clip.euler("right_knee")
    assert np.all(knee[:, 0] <= 0.05)  # knees flex backward: negative x in our convention
    assert np.ptp(knee[:, 0]) > math.radians(40)
    with pytest.raises(FileNotFoundError, match="shipped"):
        load_deepmimic("moonwalk")


@pytest.mark.parametrize(("content", "says"), [
    (b"{not json", "not a DeepMimic clip"), (b"[1, 2]", "not a DeepMimic clip"),
    (bytes(range(128, 256)), "not a DeepMimic clip"), (b'{"Frames": [[0, 1], [2]]}', "frames are not rows of numbers"),
    (b'{"Frames": [[0.1, 2, 3]]}', "expected frames of"),
])
def test_a_broken_clip_file_is_named_with_the_problem(tmp_path: Path, content: bytes, says: str) -> None:
    clip = tmp_path / "mine.txt"
    clip.write_bytes(content)
    with pytest.raises(ValueError, match=f"mine.txt: {says}"):
        load_deepmimic(clip)


@pytest.mark.parametrize("name", ["punch", "dance_a", "walk"])
def test_limits_from_a_clip_contain_at_least_99_percent_of_its_frames(name: str) -> None:
    clip = load_deepmimic(name)
    limits = limits_from_clips([clip])
    assert limits.quaternion  # Algorithm 1 ran for the joints the clip moves in 3-D
    inside_all = np.ones(len(clip.times), dtype=bool)
    for joint, qlim in limits.quaternion.items():
        inside_all &= qlim.contains(clip.quaternions(joint))
    assert inside_all.mean() >= 0.99
    for joint in clip.rotations:  # the Euler boxes, where they come from the data
        if limits.sources[joint] == "mocap":
            assert limits.euler[joint].contains(clip.euler(joint)).mean() >= 0.99


def test_algorithm_1_recovers_mean_and_principal_axes() -> None:
    rng = np.random.default_rng(7)
    mean = Rotation.from_euler("XYZ", [0.4, -0.2, 0.3])
    axes = Rotation.from_euler("z", 0.5).as_matrix()  # principal directions of the spread
    spread = rng.normal(size=(4000, 3)) * np.array([0.5, 0.15, 0.03])
    samples = mean * Rotation.from_rotvec(spread @ axes.T)
    lim = quaternion_limits(samples.as_quat(), coverage=0.99)
    assert (Rotation.from_quat(lim.mean) * mean.inv()).magnitude() < 0.02
    assert abs(abs(float(lim.axes[:, 0] @ axes[:, 0])) - 1.0) < 0.01  # first principal axis
    assert lim.extents[0] > lim.extents[1] > lim.extents[2]
    assert lim.contains(samples.as_quat()).mean() >= 0.99
    outside = mean * Rotation.from_rotvec(axes[:, 2] * 0.5)  # far along the narrowest axis
    assert not lim.contains(outside.as_quat()[None, :])[0]
    projected = lim.project(outside.as_quat()[None, :])
    assert lim.radius(projected)[0] == pytest.approx(1.0, abs=1e-6)
    assert mean_quaternion(np.array([[0, 0, 0, 1.0], [0, 0, 0, -1.0]])) == pytest.approx([0, 0, 0, 1.0])


def test_bad_samples_are_rejected() -> None:
    with pytest.raises(ValueError, match="finite"):
        euler_limits(np.array([[0.0, np.nan, 0.0]]))
    with pytest.raises(ValueError, match="quaternions"):
        quaternion_limits(np.zeros((2, 4)))
