"""A skeleton whose lengths no body has is refused naming the joints each length was measured between.

An animator's Mixamo skeleton with LeftArm/RightArm renamed (and the legs, and the hips) was refused with
``no unit gives a performer 1.2 to 2.2 m tall with these lengths (143 m in metres, 1.43 m in centimetres, ...)``:
1.43 m is within 1.2 to 2.2 m, and nothing said why. LeftShoulder (Mixamo's clavicle) had been taken for the upper
arm, as Biovision's LeftShoulder is, so the shoulder width was the clavicles' roots' 5.6 cm. The refusal now says
which length is implausible and between which joints, what each other unit makes, and the joints every length was
measured between (and those not found), in ``batteur render --skeleton-bvh``, the physics node and a core built
from the skeleton.
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import pytest

from batteur import render
from common.exit_status import InputError
from common.gesture.bvh import BvhError
from services.physics import node
from services.physics.anthropometry import performer_anthropometry
from services.physics.bvh_motion import STATURE_RANGE_M, read_skeleton, usable_segment_lengths
from tests.physics.test_skeleton_names_units import MIXAMO, skeleton

RENAMED = {**MIXAMO, "hips": "Pelvis_x", "upper_arm": "{S}A", "thigh": "{S}UL"}
"""Mixamo's names with the upper arms, thighs and hips renamed (skel_bad.bvh of the walkthrough): LeftShoulder is
then the only left joint named as an upper arm may be."""
SAID = ("segment shoulder_width length 0.12 m is implausible (expected 0.15 ... 0.8 m), measured from LeftShoulder to "
        "RightShoulder, read in centimetres")
JOINTS = ("The lengths were measured between these joints, found by name (a joint named otherwise is taken for "
          "another segment or not found): upper arm LeftShoulder to LeftForeArm and RightShoulder to RightForeArm; "
          "forearm LeftForeArm to LeftHand and RightForeArm to RightHand; shank LeftLeg to LeftFoot and RightLeg to "
          "RightFoot; neck Neck to Head; shoulder width LeftShoulder to RightShoulder; no joints found for the thigh, "
          "shoulder height, hip width")


@pytest.fixture
def renamed(tmp_path: Path) -> Path:
    path = tmp_path / "skel_bad.bvh"
    path.write_text(skeleton(RENAMED), encoding="utf-8")
    return path


def test_the_refusal_names_the_implausible_length_and_the_joints(renamed: Path) -> None:
    with pytest.raises(BvhError) as caught:
        usable_segment_lengths(renamed)
    said = str(caught.value)
    assert said.startswith(f"{renamed}: {SAID}: its longest offset, 100, is over 3; "), said
    assert said.endswith(f". {JOINTS}"), said


def test_the_units_are_not_said_to_give_no_performer_where_one_is(renamed: Path) -> None:
    """Each unit's stature listed as no performer's is outside 1.2 to 2.2 m; centimetres, whose stature is within,
    is said to fail for its shoulder width (above), not its stature."""
    reading = read_skeleton(renamed)
    assert (reading.unit, reading.fits) == ("cm", False)
    stature = reading.stature_m
    assert stature is not None and STATURE_RANGE_M[0] <= stature <= STATURE_RANGE_M[1]  # the contradiction's cause
    others = reading.why.split("no other unit gives a performer's lengths either: ", 1)[1]
    assert "centimetres" not in others
    listed = {unit: float(m) for unit, m in re.findall(r"in (\w+) a ([\d.]+) m performer's", others)}
    assert set(listed) == {"metres", "millimetres", "inches"}, others
    assert all(not STATURE_RANGE_M[0] <= m <= STATURE_RANGE_M[1] for m in listed.values()), listed
    assert others.endswith("(a performer is 1.2 to 2.2 m tall)")


def test_render_the_node_and_a_core_say_the_joints(renamed: Path, tmp_path: Path) -> None:
    with pytest.raises(ValueError) as caught:
        render.check_options(render.RenderOptions(skeleton_bvh=renamed))
    assert str(caught.value).startswith(f"--skeleton-bvh: {renamed}: {SAID}") and JOINTS in str(caught.value)
    settings = node.PhysicsNodeSettings(discovery=False, skeleton_bvh=str(renamed), kit=str(tmp_path / "no.yaml"))
    with pytest.raises(InputError) as refused:
        node.make_core(settings, argparse.Namespace())
    assert SAID in str(refused.value) and JOINTS in str(refused.value)
    with pytest.raises(ValueError) as built:  # a core built without the node's check (a library's), cm given
        performer_anthropometry(1.75, 70.0, str(renamed), "cm")
    assert str(built.value).startswith(f"skeleton_bvh {renamed}: segment shoulder_width length 0.12 m is "
                                       "implausible (expected 0.15 ... 0.8 m), measured from LeftShoulder to "
                                       "RightShoulder. The lengths were measured between"), str(built.value)
