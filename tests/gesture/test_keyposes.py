"""The keyframe mode reads the pose editor's UP/DOWN key poses (poses.yaml); the shipped defaults without them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from common.gesture.heights import stick_height
from common.gesture.keyframe import DELTA, plan_keyframes
from common.gesture.keyposes import KeyPose, KeyPoses
from common.kit import EventType as E
from common.kit import Limb, load_kit
from common.score.events import DrumEvent, Score
from common.score.limbs import distribute

KIT = load_kit()
SCORE = Score([DrumEvent(0.0, E.SNARE, 0.5), DrumEvent(0.5, E.HIHATCLOSED, 0.8), DrumEvent(1.0, E.SNARE, 1.0)])
ASSIGNMENT = distribute(SCORE, KIT, "simple")


def _limb_of(event: E) -> Limb:
    return next(n.limb for n in ASSIGNMENT.notes if n.event == event)


def _frames(plan: object, limb: Limb) -> tuple[np.ndarray, np.ndarray]:
    traj = plan.trajectories[limb]  # type: ignore[attr-defined]
    return traj.times, traj.positions


def _at(times: np.ndarray, positions: np.ndarray, t: float) -> np.ndarray:
    i = int(np.flatnonzero(np.isclose(times, t))[0])
    return positions[i]


def _library(limb: Limb, lift: np.ndarray, event: E = E.SNARE) -> KeyPoses:
    down = np.array([0.0, 0.4, 0.7])
    return KeyPoses(poses={
        f"{event.value}.{limb.value}.DOWN": KeyPose(joints={"right_elbow": (60.0, 0.0, 0.0)},
                                                    effectors={limb: tuple(down)}),  # type: ignore[dict-item]
        f"{event.value}.{limb.value}.UP": KeyPose(joints={"right_elbow": (90.0, 0.0, 0.0)},
                                                  effectors={limb: tuple(down + lift)}),  # type: ignore[dict-item]
    })


def test_without_poses_the_shipped_default_applies(tmp_path: Path) -> None:
    base = plan_keyframes(ASSIGNMENT, KIT, SCORE)
    for poses in (None, KeyPoses(), tmp_path / "poses.yaml"):  # nothing, empty, a file that is not there
        plan = plan_keyframes(ASSIGNMENT, KIT, SCORE, poses=poses)
        for limb, traj in base.trajectories.items():
            assert np.array_equal(plan.trajectories[limb].positions, traj.positions)
            assert np.array_equal(plan.trajectories[limb].times, traj.times)
    # the default raises the tip along the surface normal by the velocity's height
    limb = _limb_of(E.SNARE)
    target, normal = (np.array(v) for v in KIT.effector_target(E.SNARE, limb))
    times, pos = _frames(base, limb)
    assert _at(times, pos, 1.0 - DELTA) == pytest.approx(target + stick_height(1.0) * normal)


def test_saved_up_down_poses_shape_the_strokes(tmp_path: Path) -> None:
    limb = _limb_of(E.SNARE)
    lift = np.array([0.05, -0.12, 0.25])  # back toward the drummer and up, not along the normal
    path = tmp_path / "poses.yaml"
    _library(limb, lift).save(path)
    plan = plan_keyframes(ASSIGNMENT, KIT, SCORE, poses=path)
    target, normal = (np.array(v) for v in KIT.effector_target(E.SNARE, limb))
    times, pos = _frames(plan, limb)
    elasticity = KIT.object_for(E.SNARE).elasticity
    # full velocity: the before frame is the UP pose's lift itself; the after frame its rebound share
    assert _at(times, pos, 1.0 - DELTA) == pytest.approx(target + lift)
    assert _at(times, pos, 1.0 + DELTA) == pytest.approx(target + elasticity * lift)
    # half velocity: the same direction, scaled like the default height
    scale = stick_height(0.5) / stick_height(1.0)
    assert _at(times, pos, 0.0 - DELTA) == pytest.approx(target + scale * lift)
    assert _at(times, pos, 0.0) == pytest.approx(target)  # contacts stay on the kit's hit point
    strokes = [s for s in plan.strokes if s.event == E.SNARE]
    assert strokes[1].lift == pytest.approx(float(np.linalg.norm(lift)))
    assert strokes[1].normal == pytest.approx(normal)  # the stroke still reports the surface normal
    # other events and limbs keep the default
    base = plan_keyframes(ASSIGNMENT, KIT, SCORE)
    hat = _limb_of(E.HIHATCLOSED)
    if hat != limb:
        assert np.array_equal(plan.trajectories[hat].positions, base.trajectories[hat].positions)


def test_incomplete_or_tiny_poses_fall_back_to_the_default() -> None:
    limb = _limb_of(E.SNARE)
    base = plan_keyframes(ASSIGNMENT, KIT, SCORE)
    only_up = KeyPoses(poses={k: v for k, v in _library(limb, np.array([0, 0, 0.2])).poses.items()
                              if k.endswith("UP")})
    tiny = _library(limb, np.array([0.0, 0.0, 0.001]))
    other_limb = _library(Limb.RIGHT_FOOT if limb != Limb.RIGHT_FOOT else Limb.LEFT_FOOT, np.array([0, 0, 0.2]))
    for poses in (only_up, tiny, other_limb):
        plan = plan_keyframes(ASSIGNMENT, KIT, SCORE, poses=poses)
        assert np.array_equal(plan.trajectories[limb].positions, base.trajectories[limb].positions)


def test_a_bad_poses_file_is_a_clear_error(tmp_path: Path) -> None:
    path = tmp_path / "poses.yaml"
    path.write_text("SNARE.left_hand.UP:\n  joints: {tail: [0, 0, 0]}\n", encoding="utf-8")
    with pytest.raises(ValueError, match="poses.yaml.*unknown joint 'tail'"):
        plan_keyframes(ASSIGNMENT, KIT, SCORE, poses=path)
    path.write_text("SNARE.left_hand.UP:\n  effectors: {left_hand: [0, .nan, 0]}\n", encoding="utf-8")
    with pytest.raises(ValueError, match="finite"):
        KeyPoses.load(path)
    path.write_text("[not: a mapping\n", encoding="utf-8")
    with pytest.raises(ValueError, match="not a valid poses file"):
        KeyPoses.load(path)


@pytest.mark.parametrize("name", ["SNARE.left_hand.UP\n", "SNARE..UP", "snare/UP"])
def test_a_pose_name_with_a_line_break_or_odd_characters_is_refused(name: str) -> None:
    """A name ending in a line break is refused too (a regex's ``$`` alone would let it through)."""
    with pytest.raises(ValueError, match="pose name"):
        KeyPoses.model_validate({"poses": {name: {"joints": {}}}})
