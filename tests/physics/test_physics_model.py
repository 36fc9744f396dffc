"""The generated body: 57 actuated DOF, masses and proportions from de Leva's table, BVH lengths."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pybullet as p
import pytest

from services.physics.anthropometry import (
    CLAVICLE_MIDLINE_OFFSET,
    DE_LEVA,
    REFERENCE,
    SHOULDER_BELOW_NECK,
    anthropometry,
    body_mass_of,
)
from services.physics.body import Body
from services.physics.bvh_motion import bvh_segment_lengths
from services.physics.character import (
    DOF_NAMES,
    DUMMY_MASS_KG,
    JOINTS,
    CharacterModel,
    CharacterSpec,
    build_character,
)
from services.physics.world import World


def _load(height: float = 1.75, mass: float = 73.0) -> tuple[World, Body, CharacterModel]:
    model = build_character(CharacterSpec(anthropometry(height, mass)))
    world = World()
    return world, Body(world, model, (0.0, 0.0, 1.2)), model


def _joints(world: World, body: Body) -> list[tuple[int, int]]:
    """(body id, joint) of every joint of every part."""
    c = world.client
    return [(b, j) for b in body.ids for j in range(c.getNumJoints(b))]


def test_the_body_has_19_joints_of_3_revolute_dof_57_actuated() -> None:
    world, body, model = _load()
    c = world.client
    assert len(JOINTS) == 19 and len(DOF_NAMES) == 57
    joints = _joints(world, body)
    names = [c.getJointInfo(b, j)[1].decode() for b, j in joints]
    revolute = {c.getJointInfo(b, j)[1].decode() for b, j in joints if c.getJointInfo(b, j)[2] == p.JOINT_REVOLUTE}
    assert len(names) == len(set(names))  # no DOF twice across the parts
    passive = set(model.passive)
    assert passive == {"left_fulcrum_x", "left_fulcrum_z", "right_fulcrum_x", "right_fulcrum_z"}
    assert revolute - passive == set(DOF_NAMES)
    assert not any(c.getJointInfo(b, j)[2] == p.JOINT_SPHERICAL for b, j in joints)
    # each joint's three DOF are about x, y, z in turn
    for name in DOF_NAMES:
        axis = c.getJointInfo(*body.link_ref[body.joint_index[name]])[13]
        assert axis == tuple(1.0 if a == name[-1] else 0.0 for a in "xyz")
    # the legs are their own multibodies, based on the throne at the hips (the pelvis rocking does not move them)
    assert len(body.ids) == 3
    for side in ("left", "right"):
        leg, _ = body.link_ref[body.joint_index[f"{side}_hip_x"]]
        assert leg != body.id
        assert {c.getJointInfo(leg, j)[1].decode() for j in range(c.getNumJoints(leg))} >= {
            f"{side}_{joint}_{axis}" for joint in ("hip", "knee", "ankle") for axis in "xyz"}
    world.close()


@pytest.mark.parametrize(("height", "mass"), [(1.75, 73.0), (1.60, 55.0), (1.92, 95.0)])
def test_total_mass_matches_the_body_mass(height: float, mass: float) -> None:
    a = anthropometry(height, mass)
    assert body_mass_of(a) == pytest.approx(mass, rel=1e-3)
    world, body, model = _load(height, mass)
    c = world.client
    # every link of every part; the bases (the seat's cushion on the throne, the hip mounts) are not the body's
    total = sum(c.getDynamicsInfo(b, j)[0] for b in body.ids for j in range(c.getNumJoints(b)))
    stick = 2 * (model.spec.stick.mass_kg + 1e-4)
    markers = 4 * 1e-4 + 2 * 1e-4  # tips, aims, balls of the feet
    dummies = 2 * 19 * DUMMY_MASS_KG + 2 * DUMMY_MASS_KG  # two per joint, one per fulcrum
    assert total - stick - markers - dummies == pytest.approx(mass, rel=1e-3)
    world.close()


def test_segment_lengths_and_masses_follow_de_leva_scaled_by_height_and_mass() -> None:
    height, mass = 1.90, 88.0
    a = anthropometry(height, mass)
    ref_h, _ = REFERENCE["male"]
    scale = height * 1000 / ref_h
    table = DE_LEVA["male"]
    for ours, theirs in (("upper_arm", "upper_arm"), ("forearm", "forearm"), ("thigh", "thigh"),
                         ("shank", "shank"), ("foot", "foot"), ("hand", "hand")):
        seg = a.segments[ours]
        assert seg.length_m == pytest.approx(table[theirs].length_mm / 1000 * scale, rel=1e-9)
        assert seg.mass_kg == pytest.approx(table[theirs].mass_pct / 100 * mass, rel=1e-9)
        assert seg.com_from_proximal_m == pytest.approx(table[theirs].com_pct / 100 * seg.length_m)
    # proportions in the generated body: joint centres are as far apart as the table says
    world, body, model = _load(height, mass)

    def pos(name: str) -> np.ndarray:
        return body.link_pose(body.joint_index[name])[0]

    for upper, lower, name in (("right_shoulder_x", "right_elbow_x", "upper_arm"),
                              ("right_elbow_x", "right_wrist_x", "forearm"),
                              ("left_hip_x", "left_knee_x", "thigh"), ("left_knee_x", "left_ankle_x", "shank")):
        assert float(np.linalg.norm(pos(upper) - pos(lower))) == pytest.approx(a.segments[name].length_m, rel=1e-6)
    # standing zero pose: stature within a few percent of the height (feet on the ground, head on top)
    world.close()


def test_bad_anthropometry_is_rejected() -> None:
    with pytest.raises(ValueError, match="height"):
        anthropometry(3.0, 70.0)
    with pytest.raises(ValueError, match="mass"):
        anthropometry(1.7, 10.0)
    with pytest.raises(ValueError, match="unknown segment"):
        anthropometry(1.7, 70.0, lengths_m={"tail": 0.3})
    with pytest.raises(ValueError, match="not both"):
        anthropometry(1.7, 70.0, lengths_m={"trunk": 0.6, "shoulder_height": 0.55})
    with pytest.raises(ValueError, match="shoulder_width length 2.0 m is implausible"):
        anthropometry(1.7, 70.0, lengths_m={"shoulder_width": 2.0})
    with pytest.raises(ValueError, match="trunk length -0.1 m"):  # a skeleton upside down
        anthropometry(1.7, 70.0, lengths_m={"trunk": -0.1})


def test_a_whole_trunk_keeps_the_tables_proportions() -> None:
    table = anthropometry(1.75, 73.0)
    trunk = ("pelvis", "abdomen", "thorax")
    table_trunk = sum(table.segments[n].length_m for n in trunk)
    a = anthropometry(1.75, 73.0, lengths_m={"shoulder_height": 0.6, "shoulder_width": 0.4, "hip_width": 0.2})
    assert sum(a.segments[n].length_m for n in trunk) == pytest.approx(0.6 + SHOULDER_BELOW_NECK * a.scale)
    for n in trunk:
        assert a.segments[n].length_m / table.segments[n].length_m == pytest.approx(
            (0.6 + SHOULDER_BELOW_NECK * a.scale) / table_trunk)
        assert a.segments[n].mass_kg == table.segments[n].mass_kg
    assert (a.shoulder_width_m, a.hip_width_m) == (0.4, 0.2)
    assert a.segments["clavicle"].length_m == pytest.approx(0.2 - CLAVICLE_MIDLINE_OFFSET * a.scale)
    # a segment named itself wins over the trunk it is part of
    b = anthropometry(1.75, 73.0, lengths_m={"trunk": 0.7, "pelvis": 0.1})
    assert b.segments["pelvis"].length_m == 0.1


def test_segment_lengths_from_a_bvh_skeleton(tmp_path: Path) -> None:
    bvh = tmp_path / "arm.bvh"
    bvh.write_text(
        "HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation "
        "Yrotation\n JOINT RightUpLeg\n {\n  OFFSET -9 0 0\n  CHANNELS 3 Zrotation Xrotation Yrotation\n"
        "  JOINT RightLeg\n  {\n   OFFSET 0 -44 0\n   CHANNELS 3 Zrotation Xrotation Yrotation\n"
        "   JOINT RightFoot\n   {\n    OFFSET 0 -42 0\n    CHANNELS 3 Zrotation Xrotation Yrotation\n"
        "    End Site\n    {\n     OFFSET 0 -5 10\n    }\n   }\n  }\n }\n}\nMOTION\nFrames: 1\nFrame Time: 0.01\n"
        + " ".join(["0"] * 15) + "\n",
        encoding="utf-8",
    )
    lengths = bvh_segment_lengths(bvh)
    assert lengths == pytest.approx({"thigh": 0.44, "shank": 0.42})
    a = anthropometry(1.75, 73.0, lengths_m=lengths)
    assert a.segments["thigh"].length_m == pytest.approx(0.44)
    assert math.isclose(a.segments["thigh"].mass_kg, anthropometry(1.75, 73.0).segments["thigh"].mass_kg)


def test_inverse_dynamics_of_the_body_match_pybullets() -> None:
    """The controller's compiled inverse dynamics give PyBullet's torques for the same state (the three parts'
    fixed-base trees, sticks and fingers included), against ``calculateInverseDynamics`` on each part."""
    from services.physics.kernels import inverse_dynamics

    world, body, _ = _load(1.62, 58.0)
    tree = body.dynamics_tree()
    rng = np.random.default_rng(3)
    m = len(body.state_joints)
    for _ in range(5):
        state = np.vstack([rng.uniform(-1, 1, m), rng.uniform(-4, 4, m), rng.uniform(-80, 80, m)])
        expected = np.zeros(m)
        for part in body.parts:  # each part's revolute joints are state joints, in its own joint order
            slots = [body.state_joints.index(part.offset + j) for j in part.movable]
            q, qd, qdd = (state[row, slots].tolist() for row in range(3))
            expected[slots] = world.client.calculateInverseDynamics(part.id, q, qd, qdd)
        tau = inverse_dynamics(state, *tree, world.settings.gravity)
        assert np.abs(expected).max() > 50.0  # loaded joints: the comparison is not of zeros
        np.testing.assert_allclose(tau, expected, rtol=0, atol=1e-6 * np.abs(expected).max())
    world.close()
