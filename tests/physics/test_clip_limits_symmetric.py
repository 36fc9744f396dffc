"""Limits from the user's own clips (``limits_from``, ``--limits-from``) are made mirror-symmetric as the default
ones are (``limits.symmetric_limits``): a side the clips let reach further drifted there and lost fast kicks
(docs/physics.md, "Symmetric limits"). ``asymmetric_limits`` (``--asymmetric-limits``) keeps each side's own, for a
performer with a real asymmetry; ``--show-body`` and report.json say which was used."""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from services.physics.body_table import body_json, body_text
from services.physics.character import JOINTS
from services.physics.core import PhysicsCore
from services.physics.limits import JointLimits, limits_from_clips, load_clip, mirrored_limit

PAIRED = [joint[len("right_"):] for joint in JOINTS if joint.startswith("right_")]
CLIP = "kick"
"""A clip that favours a side: its right leg kicks."""


def _mirror_pairs(limits: JointLimits) -> dict[str, bool]:
    """Paired joint kind -> whether the right box is the left's mirrored (pairs grown to the posture left out)."""
    out = {}
    for kind in PAIRED:
        right, left = f"right_{kind}", f"left_{kind}"
        if "+posture" in limits.sources[right] or "+posture" in limits.sources[left]:
            continue
        mirrored = mirrored_limit(limits.euler[left])
        out[kind] = bool(np.allclose(limits.euler[right].lower, mirrored.lower, atol=1e-12)
                         and np.allclose(limits.euler[right].upper, mirrored.upper, atol=1e-12))
    return out


@pytest.fixture(scope="module")
def drummers() -> Iterator[dict[bool, PhysicsCore]]:
    """Drummers with the kick clip's limits: symmetric (the default) and asymmetric."""
    cores = {asym: PhysicsCore(scene="drummer", limits_from=(CLIP,), asymmetric_limits=asym) for asym in (False, True)}
    yield cores
    for core in cores.values():
        core.close()


def test_a_drummers_clip_limits_are_mirror_symmetric_by_default(drummers: dict[bool, PhysicsCore]) -> None:
    scene = drummers[False].scene
    limits = scene.limits
    assert limits.symmetric
    pairs = _mirror_pairs(limits)
    assert len(pairs) >= 4 and all(pairs.values()), pairs
    assert any("+symmetric" in source for source in limits.sources.values())
    # the body's revolute limits are these boxes
    for k, joint in enumerate(JOINTS):
        assert scene.body.lower[3 * k:3 * k + 3] == pytest.approx(limits.euler[joint].lower, abs=1e-9), joint
        assert scene.body.upper[3 * k:3 * k + 3] == pytest.approx(limits.euler[joint].upper, abs=1e-9), joint
    assert body_json(scene)["limits_symmetric"] is True
    assert f"limits from: {CLIP} (mirror-symmetric)" in body_text(scene)


def test_asymmetric_limits_keep_each_sides_own_estimate(drummers: dict[bool, PhysicsCore]) -> None:
    scene = drummers[True].scene
    limits = scene.limits
    assert not limits.symmetric
    assert not any("+symmetric" in source for source in limits.sources.values())
    assert not all(_mirror_pairs(limits).values())  # the kick's legs differ
    raw = limits_from_clips([load_clip(CLIP)])
    for joint in JOINTS:
        if "+posture" not in limits.sources[joint]:
            assert limits.euler[joint].upper == pytest.approx(raw.euler[joint].upper, abs=1e-12), joint
    assert body_json(scene)["limits_symmetric"] is False
    assert "each side its own: --asymmetric-limits" in body_text(scene)


@pytest.mark.parametrize("symmetric", [False, True])
def test_the_playing_posture_is_held_after_the_boxes_are_made_symmetric(symmetric: bool) -> None:
    """A posture within one side's own range but outside the other's mirrored one: the symmetric box, cut to the
    common range, grows back to hold it (``+posture``), as a box the clips never bring there does."""
    clip = load_clip(CLIP)
    raw = limits_from_clips([clip])
    common = limits_from_clips([clip], symmetric=True)
    side = next(j for j in JOINTS if j.startswith(("right_", "left_"))
                and common.euler[j].upper[0] < raw.euler[j].upper[0] - math.radians(2.0))
    need = (raw.euler[side].lower + raw.euler[side].upper) / 2
    need[0] = raw.euler[side].upper[0] - math.radians(1.0)  # inside its own box, outside the common one
    limits = limits_from_clips([clip], must_contain={side: need}, symmetric=symmetric)
    assert limits.symmetric is symmetric
    assert bool(limits.euler[side].contains(need)[0])
    if symmetric:
        assert "+posture" in limits.sources[side] and "+symmetric" in limits.sources[side]
    if side in limits.quaternion:  # an ellipsoid kept holds it too
        assert bool(limits.quaternion[side].contains(Rotation.from_euler("XYZ", need).as_quat()[None])[0])
