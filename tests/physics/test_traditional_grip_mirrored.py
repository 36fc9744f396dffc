"""The traditional grip holds the snare hand underhand, the hand that does not lead: the left on a right-handed kit,
the right on a left-handed one (until 7 Dec the left whatever the kit: a lefty's leading hand was underhand)."""

from __future__ import annotations

import numpy as np
import pytest

from services.physics.core import PhysicsCore
from services.physics.drummer import JOINTS, DrummerScene, grip_for, underhand_side


def _elbow_z_and_springs(kit: str) -> tuple[dict[str, float], np.ndarray]:
    """The built drummer's rest forearm pronation per side (elbow z, rad) and its finger springs (N m/rad, [left x,
    left z, right x, right z]) holding the traditional grip on ``kit``."""
    core = PhysicsCore(scene="drummer", grip="traditional", kit=kit, pose_rate_hz=0)
    try:
        assert isinstance(core.scene, DrummerScene)
        scene = core.scene
        pronation = {side: float(scene.rest[JOINTS.index(f"{side}_elbow") * 3 + 2]) for side in ("left", "right")}
        springs = -scene.passive_torques(np.ones(4), np.zeros(4))
        return pronation, springs
    finally:
        core.close()


def test_a_left_handed_drummer_holds_the_right_stick_underhand() -> None:
    right_handed, right_springs = _elbow_z_and_springs("default")
    left_handed, left_springs = _elbow_z_and_springs("left_handed")
    underhand = grip_for("traditional", "left").pronation  # the right-handed kit's left hand
    assert right_handed["left"] == pytest.approx(-underhand)  # the left forearm's sign: -1
    # mirrored: each side's pronation is the other side's of the right-handed drummer, negated
    assert left_handed["right"] == pytest.approx(-right_handed["left"], abs=1e-6)
    assert left_handed["left"] == pytest.approx(-right_handed["right"], abs=1e-6)
    assert left_springs == pytest.approx(np.concatenate([right_springs[2:], right_springs[:2]]))


def test_the_underhand_side_is_the_hand_that_does_not_lead() -> None:
    assert underhand_side("right") == "left" and underhand_side("left") == "right"
    assert grip_for("traditional", "right", "left") == grip_for("traditional", "left", "right")
    assert grip_for("traditional", "left", "left") == grip_for("american", "left", "left")
    assert grip_for("german", "right", "left") == grip_for("german", "right", "right")  # matched grips: alike
