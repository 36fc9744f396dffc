"""Skeleton inference, pose sequences and the synthetic drummer the other graphics tests rely on."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from services.graphics.figure import LINK_NAMES, SyntheticDrummer, hit_point
from services.graphics.sequence import PoseSequence
from services.graphics.skeleton import guess_parents


def test_parents_from_names_with_aliases_sides_and_gaps() -> None:
    names = ["root", "spine", "head", "shoulder_l", "l_elbow", "left_wrist", "right_forearm", "R_hand",
             "right_stick_tip", "ride", "hip_r", "right_knee"]
    parents = dict(zip(names, (names[p] if p >= 0 else None for p in guess_parents(names)), strict=True))
    assert parents["root"] is None and parents["spine"] == "root"
    assert parents["head"] == "spine"  # no neck or chest: the nearest ancestor present
    assert parents["l_elbow"] == "shoulder_l" and parents["left_wrist"] == "l_elbow"
    assert parents["right_forearm"] == "spine"  # no right upper arm
    assert parents["R_hand"] == "right_forearm" and parents["right_stick_tip"] == "R_hand"
    assert parents["ride"] is None  # a kit link, not a body part
    assert parents["right_knee"] == "hip_r" and parents["hip_r"] == "root"


def test_pose_sequence_checks_its_input_and_interpolates() -> None:
    with pytest.raises(ValueError, match="shape"):
        PoseSequence(["a"], np.array([0.0, 1.0]), np.zeros((2, 2, 7)))
    with pytest.raises(ValueError, match="increasing"):
        PoseSequence(["a"], np.array([1.0, 0.0]), np.zeros((2, 1, 7)))
    with pytest.raises(ValueError, match="finite"):
        PoseSequence(["a"], np.array([0.0]), np.full((1, 1, 7), np.nan))
    values = np.zeros((2, 1, 7))
    values[:, 0, 6] = 1.0
    values[1, 0, :3] = [1.0, 2.0, 3.0]
    seq = PoseSequence(["a"], np.array([0.0, 2.0]), values)
    assert seq.sample(0.5)[0, :3] == pytest.approx([0.25, 0.5, 0.75])
    assert seq.sample(-1.0)[0, :3] == pytest.approx([0, 0, 0]) and seq.sample(9.0)[0, 0] == 1.0
    assert len(seq.resample(10.0).times) == 21


def test_synthetic_drummer_is_rigid_and_strikes_its_targets_on_time(tmp_path: object) -> None:
    drummer = SyntheticDrummer(duration=2.5)
    seq = drummer.sequence(60.0)
    parents = guess_parents(LINK_NAMES)
    assert all(p >= 0 for p in parents[1:])  # one tree
    offsets = []
    for frame in seq.values[::15]:
        offsets.append([Rotation.from_quat(frame[p, 3:]).inv().apply(frame[i, :3] - frame[p, :3])
                        for i, p in enumerate(parents) if p >= 0])
    assert np.ptp(np.array(offsets), axis=0).max() < 1e-9  # constant offsets: a rigid articulated body
    impacts = drummer.impacts()
    assert {i.instrument for i in impacts} >= {"hihat", "snare", "kick", "crash"}
    for imp in impacts:
        if imp.part.endswith("stick_tip"):
            stroke = next(s for s in drummer.strokes[f"{imp.part.split('_')[0]}_hand"] if s.time == imp.time)
            tip = drummer.pose(imp.time)[LINK_NAMES.index(imp.part), :3]
            assert np.linalg.norm(tip - hit_point(drummer.kit, stroke.event)[0]) < 0.03, imp
