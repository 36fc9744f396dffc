"""Joint limits from motion capture (Euler statistics and the quaternion Algorithm 1), enforced in simulation."""

from __future__ import annotations

import logging
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from services.physics.limits import (
    anatomical_limit,
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
    (b'{"Frames": [[' + b", ".join([b"0"] * 44) + b"], [" + b", ".join([b"0"] * 9 + [b"NaN"] + [b"0"] * 34) + b"]]}",
     # was "non-finite values"
     r"frame 2 of 2, value 10 \(chest x; both counted from 1\) is not finite \(nan\)"),
])
def test_a_broken_clip_file_is_named_with_the_problem(tmp_path: Path, content: bytes, says: str) -> None:
    clip = tmp_path / "mine.txt"
    clip.write_bytes(content)
    with pytest.raises(ValueError, match=f"mine.txt: {says}"):
        load_deepmimic(clip)


@pytest.mark.parametrize("name", ["punch", "dance_a", "walk", None])
def test_limits_from_clips_hold_their_frames_as_the_docs_say(name: str | None) -> None:
    """Per DOF, by where its range comes from (``dof_sources``, docs/physics.md "Joint limits"): a ``mocap`` range
    holds every frame of the clips it comes from; a ``still`` or ``wraps`` DOF has the anatomical range, and a
    joint with a ``wraps`` DOF is held by its ellipsoid (its Euler box does not hold the frames: the punch's right
    shoulder 61.5 %, all 15 clips' shoulders 87.7 and 90.3 %). ``None``: the 15 clips of the default limits."""
    clips = [load_deepmimic(n) for n in ([name] if name else deepmimic_clip_names())]
    limits = limits_from_clips(clips)
    assert limits.quaternion  # Algorithm 1 ran for the joints the clips move in 3-D
    for joint, qlim in limits.quaternion.items():
        assert qlim.contains(np.concatenate([c.quaternions(joint) for c in clips])).mean() >= 0.99, joint
    coverage: dict[str, list[float]] = {}  # DOF source -> the share of frames each such DOF's range holds
    for joint in clips[0].rotations:
        euler = np.concatenate([c.euler(joint) for c in clips])
        box, anatomical = limits.euler[joint], anatomical_limit(joint)
        for i, source in enumerate(limits.dof_sources[joint]):
            held = float(np.mean((euler[:, i] >= box.lower[i]) & (euler[:, i] <= box.upper[i])))
            coverage.setdefault(source, []).append(held)
            if source == "mocap":  # the clips' own frames decide the range
                assert held >= 0.99, (joint, i, held)
            else:
                assert source in ("still", "wraps")
                assert (box.lower[i], box.upper[i]) == (anatomical.lower[i], anatomical.upper[i])
        if "wraps" in limits.dof_sources[joint]:
            assert joint in limits.quaternion
        if limits.sources[joint] == "mocap":
            assert limits.dof_sources[joint] == ("mocap",) * 3
            assert box.contains(euler).mean() >= 0.99
    print(name or "15 clips", {source: round(min(held), 3) for source, held in coverage.items()})
    if name == "punch":  # its right shoulder's long-axis angle wraps: outside the anatomical z range
        assert limits.dof_sources["right_shoulder"] == ("mocap", "mocap", "wraps")
        assert min(coverage["wraps"]) < 0.99


def test_limits_name_the_joints_whose_ellipsoid_the_posture_dropped() -> None:
    """``must_contain`` (the playing posture) outside a joint's clips: its box grows, its ellipsoid is dropped and
    named in ``dropped`` and in the formulations report; joints without an ellipsoid (a knee) are not named."""
    punch = load_deepmimic("punch")
    seated = {"right_hip": np.radians([95.0, 0.0, 0.0]), "right_knee": np.radians([-140.0, 0.0, 0.0])}
    assert "right_hip" in limits_from_clips([punch]).quaternion
    limits = limits_from_clips([punch], must_contain=seated)
    assert limits.dropped == ("right_hip",)
    assert limits.sources["right_hip"] == "mocap+posture" and limits.sources["right_knee"].endswith("+posture")
    report = limits.formulations()
    assert report["right_hip"] == {"formulation": "euler", "source": "mocap+posture", "dofs": ["mocap"] * 3}
    assert report["left_hip"]["formulation"] == "euler+quaternion"
    assert report["right_knee"]["formulation"] == "euler" and report["seat"]["source"] == "anatomical"
    line = limits.dropped_summary()
    assert line is not None and "at right_hip:" in line and "right_knee" not in line and "left_hip" in line
    assert limits_from_clips([punch]).dropped_summary() is None


def test_a_drummer_with_limits_from_one_clip_says_which_ellipsoids_it_dropped(
        caplog: pytest.LogCaptureFixture) -> None:
    """``limits_from=("punch",)``: a standing clip never reaches the seated posture at most joints; the drummer's
    build says which lost their quaternion limit (it was silent), and the default drummer says nothing."""
    from batteur.render import joint_limits_json
    from services.physics.core import PhysicsCore

    caplog.set_level(logging.WARNING, logger="batteur.physics")
    core = PhysicsCore(scene="drummer", pose_rate_hz=0, limits_from=("punch",))
    limits = core.scene.limits  # type: ignore[attr-defined]
    core.close()
    assert set(limits.dropped) >= {"right_shoulder", "left_hip", "right_hip"}
    assert "left_shoulder" not in limits.quaternion  # the idle arm's: dropped before, as one-sided (mirrored limits)
    said = [r.getMessage() for r in caplog.records if "joint limits from punch" in r.getMessage()]
    assert len(said) == 1 and f"at {', '.join(limits.dropped)}:" in said[0]
    assert "grown to hold the posture" in said[0] and f"kept: {', '.join(limits.quaternion)}" in said[0]
    report = joint_limits_json(core)  # report.json's physics.joint_limits
    assert report is not None
    assert {j for j, v in report.items() if v["formulation"] == "euler+quaternion"} == set(limits.quaternion)
    assert all("+posture" in report[j]["source"] for j in limits.dropped)
    caplog.clear()
    PhysicsCore(scene="drummer", pose_rate_hz=0).close()
    assert not [r for r in caplog.records if "joint limits" in r.getMessage()]


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
