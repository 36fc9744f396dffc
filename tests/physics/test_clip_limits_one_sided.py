"""Symmetric limits from a one-sided clip (``--limits-from punch``: the right arm strikes, the left hangs): the idle
side's narrow range is the absence of data, not a limit, so a DOF whose common range is under half the wider side's
takes what either side moved through, mirrored (``+mirrored``), with one warning naming the joints; where both sides
move alike (the shipped DeepMimic clips together) the boxes stay cut to the common range
(``limits.symmetric_limits``)."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from services.physics.character import JOINTS
from services.physics.limits import default_limits, limits_from_clips, load_clip, mirrored_limit, symmetric_limits

PAIRED = [joint[len("right_"):] for joint in JOINTS if joint.startswith("right_")]


def _holds(outer_lower: np.ndarray, outer_upper: np.ndarray, inner_lower: np.ndarray, inner_upper: np.ndarray) -> bool:
    return bool(np.all(outer_lower <= inner_lower + 1e-12) and np.all(outer_upper >= inner_upper - 1e-12))


def _one_sided_warnings(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [r.getMessage() for r in caplog.records if "one side much more than the other" in r.getMessage()]


@pytest.mark.parametrize(("clip", "side", "kinds", "dofs"), [("punch", "right", ["shoulder"], [0, 1, 2]),
                                                             ("kick", "right", ["hip", "knee", "ankle"], [0])])
def test_the_moving_side_of_a_one_sided_clip_keeps_its_range(clip: str, side: str, kinds: list[str], dofs: list[int],
                                                             caplog: pytest.LogCaptureFixture) -> None:
    """``dofs``: those the clip moves on one side (the kick's hip y and z both sides move alike: cut as before)."""
    # was: punch's right shoulder cut from 216/80/180 degrees to 76/35/44, kick's right hip x 65 -> 27, knee 106 -> 50
    motion = load_clip(clip)
    own = limits_from_clips([motion])
    with caplog.at_level(logging.WARNING, logger="batteur.physics.limits"):
        sym = limits_from_clips([motion], symmetric=True)
    for kind in kinds:
        joint, other = f"{side}_{kind}", f"{'left' if side == 'right' else 'right'}_{kind}"
        assert _holds(sym.euler[joint].lower[dofs], sym.euler[joint].upper[dofs], own.euler[joint].lower[dofs],
                      own.euler[joint].upper[dofs]), joint
        mirrored = mirrored_limit(sym.euler[joint])  # both sides the same, mirrored
        assert np.allclose(sym.euler[other].lower, mirrored.lower) and np.allclose(sym.euler[other].upper,
                                                                                     mirrored.upper)
        assert "+mirrored" in sym.sources[other] and "+symmetric" not in sym.sources[other]
    (said,) = _one_sided_warnings(caplog)  # once, naming the joints
    assert all(kind in said for kind in kinds)


def test_the_idle_sides_ellipsoid_is_dropped(caplog: pytest.LogCaptureFixture) -> None:
    """The left shoulder's ellipsoid in a punch holds a hanging arm's few samples: it would cut the mirrored box."""
    motion = load_clip("punch")
    own = limits_from_clips([motion])
    with caplog.at_level(logging.WARNING, logger="batteur.physics.limits"):
        sym = limits_from_clips([motion], symmetric=True)
    assert "left_shoulder" in own.quaternion and "left_shoulder" not in sym.quaternion
    assert "right_shoulder" in sym.quaternion  # the moving side's own motion: kept
    assert "the quaternion limits of left_shoulder are dropped" in caplog.text


def test_the_shipped_clips_keep_the_common_range(caplog: pytest.LogCaptureFixture) -> None:
    """The default limits (all DeepMimic clips, both sides moving alike) are each pair's common range, as before."""
    own = default_limits()
    with caplog.at_level(logging.WARNING, logger="batteur.physics.limits"):
        sym = symmetric_limits(own)
    assert _one_sided_warnings(caplog) == []
    assert not any("+mirrored" in source for source in sym.sources.values())
    assert sym.quaternion.keys() == own.quaternion.keys()
    for kind in PAIRED:
        right, left = own.euler[f"right_{kind}"], mirrored_limit(own.euler[f"left_{kind}"])
        common_lower, common_upper = np.maximum(right.lower, left.lower), np.minimum(right.upper, left.upper)
        assert np.array_equal(sym.euler[f"right_{kind}"].lower, common_lower), kind
        assert np.array_equal(sym.euler[f"right_{kind}"].upper, common_upper), kind
