"""The drummer scene: strokes give contacts, limits hold, bad targets are refused, runs are reproducible."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pybullet as p
import pytest
from scipy.spatial.transform import Rotation

from common.gesture.plan import GesturePlan, HeadTrajectory, LimbTrajectory
from common.kit import EventType, Limb, load_kit
from common.messages import Contact, Pose, Skeleton
from common.messages.physics import (
    CartesianTarget,
    JointTarget,
    PhysicsControlMode,
    PhysicsGains,
    PhysicsGrip,
    PhysicsIk,
    PhysicsReset,
)
from services.physics.body import LIMBS
from services.physics.character import DOF_NAMES, JOINTS
from services.physics.core import PhysicsCore
from services.physics.drummer import DrummerScene
from services.physics.kernels import clip_torques
from services.physics.strokes import strokes_knots
from services.physics.targets import TargetError


def _snare(core: PhysicsCore) -> tuple[np.ndarray, np.ndarray]:
    kit = core.kit
    spec = kit.events[EventType.SNARE]
    obj = kit.object(spec.object)
    r = spec.r * obj.radius
    hit = np.array(obj.to_world((r * math.cos(spec.theta), r * math.sin(spec.theta), 0.0)))
    return hit, np.array(obj.normal())


def _scene(core: PhysicsCore) -> DrummerScene:
    assert isinstance(core.scene, DrummerScene)
    return core.scene


def _run(core: PhysicsCore, t0: float, t1: float) -> list[Contact]:
    out: list[Contact] = []
    for k in range(round(t0 * 1000) + 1, round(t1 * 1000) + 1):
        out += [o.message for o in core.step(k / 1000) if isinstance(o.message, Contact)]
    return out


def _stroke_contacts(control: str, times: list[float], speeds: list[float], until: float) -> list[Contact]:
    core = PhysicsCore(scene="drummer", control=control)
    scene = _scene(core)
    hit, normal = _snare(core)
    ts, ps, vs = strokes_knots(scene.rest_targets["left_hand"], hit, normal, times, speeds)
    for k in range(len(ts)):
        scene.add_cartesian("left_hand", float(ts[k]), ps[k], vs[k], 0.0)
    contacts = _run(core, 0.0, until)
    core.close()
    return [c for c in contacts if c.instrument == "snare" and c.part.startswith("left_stick")]


def test_a_stroke_onto_the_snare_gives_one_short_contact_with_rebound() -> None:
    core = PhysicsCore(scene="drummer", control="cartesian")
    scene = _scene(core)
    hit, normal = _snare(core)
    ts, ps, vs = strokes_knots(scene.rest_targets["left_hand"], hit, normal, [0.3], [1.5])
    for k in range(len(ts)):
        scene.add_cartesian("left_hand", float(ts[k]), ps[k], vs[k], 0.0)
    contacts: list[Contact] = []
    tip_normal_speed: dict[int, float] = {}
    for k in range(1, 501):
        contacts += [o.message for o in core.step(k / 1000)
                     if isinstance(o.message, Contact) and o.message.instrument == "snare"]
        _, tip_velocity, _ = core.world.link_velocity(scene.body.id, scene.body.tip_links["left_hand"])
        tip_normal_speed[k] = float(tip_velocity @ normal)
    steps = [c.step for c in contacts]
    assert contacts, "the stick never reached the snare"
    assert steps == list(range(steps[0], steps[0] + len(steps))), f"more than one contact: {steps}"
    assert 1 <= len(steps) <= 10  # 1-10 ms at 1 kHz
    first = contacts[0]
    assert abs(first.time - 0.3) < 0.01
    assert first.part == "left_stick_tip" and first.normal_velocity > 0.5
    assert tip_normal_speed[steps[0] - 1] < -0.5  # coming down ...
    assert tip_normal_speed[steps[-1] + 1] > 0.2  # ... and bouncing back up right after the contact
    core.close()


def test_a_loud_stroke_onto_the_snare_leaves_the_head_within_10_ms() -> None:
    """At 5 m/s the shoulder is at its torque limit through the contact: clipped joint by joint, the elbow's and
    wrist's torques (computed for an upper-arm deceleration that does not happen) spun the forearm and hand, which
    stopped late and held the stick on the head for 20 steps (docs/physics.md, "Contact durations in the drummer
    scene")."""
    contacts = _stroke_contacts("cartesian", [0.3], [5.0], 0.45)
    steps = [c.step for c in contacts]
    assert contacts and contacts[0].normal_velocity > 4.0, [c.normal_velocity for c in contacts[:1]]
    assert steps == list(range(steps[0], steps[0] + len(steps))), f"more than one contact: {steps}"
    assert len(steps) <= 10, steps  # at most 10 ms at 1 kHz


def test_torques_over_their_limits_keep_the_other_joints_accelerations() -> None:
    """Controller.fit_torque_limits: torques within the limits are left as they are; an arm's DOF over its limit is
    held at it and every other DOF keeps the acceleration the computed-torque PD asked of it (joint-by-joint clipping
    does not: the others' torques were computed for the clipped DOF's acceleration)."""
    core = PhysicsCore(scene="drummer", control="cartesian")
    body, controller = _scene(core).body, _scene(core).controller
    theta, theta_dot = body.state()
    passive = body.passive_state()
    limit = body.torque_limit
    zero = np.zeros_like(theta)

    def commanded(target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        tau = controller.computed_torque(theta, theta_dot, target, zero, zero, passive)
        assert controller._ct_state is not None
        return tau, controller._ct_state.copy()

    small, state = commanded(theta + 0.001)
    assert np.all(np.abs(small) < limit)
    assert controller.fit_torque_limits(small, state) is small  # within the limits: unchanged
    target = theta.copy()
    target[DOF_NAMES.index("left_shoulder_x")] += 0.6  # an arm swung hard: the shoulder far over its limit
    tau, state = commanded(target)
    arms = controller.fit_dof  # clavicles to wrists
    over = (np.abs(tau) > limit) & arms
    assert over[DOF_NAMES.index("left_shoulder_x")] and over.sum() < arms.sum() // 2  # others left to fit
    fitted = controller.fit_torque_limits(tau, state)
    assert np.all(np.abs(fitted[arms]) <= limit[arms])
    assert np.all(fitted[over] == np.copysign(limit, tau)[over])
    # the accelerations the fitted torques give: M qdd = tau - (C + g)
    mass = controller._mass_matrix(np.concatenate([theta, passive[0]]), len(theta))
    bias = controller._bias_torque(theta, theta_dot, passive)
    free = ~(arms & (np.abs(fitted) >= limit))  # all but the arms' DOF held at their limits
    accel = np.linalg.solve(mass, fitted - bias)
    np.testing.assert_allclose(accel[free], state[2, :len(theta)][free], rtol=1e-6, atol=1e-6 * np.abs(state[2]).max())
    clipped = np.linalg.solve(mass, np.clip(tau, -limit, limit) - bias)
    assert not np.allclose(clipped[free], state[2, :len(theta)][free], rtol=1e-3, atol=1e-3)
    core.close()


def test_a_torque_the_fit_cannot_solve_for_is_left_for_the_caller_to_clip(monkeypatch: pytest.MonkeyPatch) -> None:
    """Controller.fit_torque_limits: an infinite torque over its limit (its correction is inf - inf) made every arm
    DOF's torque NaN; it, and a solve that fails (LinAlgError), leave the torques as they were: the caller clips them
    joint by joint, as before the fit."""
    core = PhysicsCore(scene="drummer", control="cartesian")
    body, controller = _scene(core).body, _scene(core).controller
    theta, theta_dot = body.state()
    zero = np.zeros_like(theta)
    target = theta.copy()
    target[DOF_NAMES.index("left_shoulder_x")] += 0.6  # the shoulder over its limit, as in the test above
    tau = controller.computed_torque(theta, theta_dot, target, zero, zero, body.passive_state())
    assert controller._ct_state is not None
    state = controller._ct_state.copy()
    limit, arms = body.torque_limit, controller.fit_dof
    assert np.all(np.isfinite(controller.fit_torque_limits(tau, state)))  # fitted
    infinite = tau.copy()
    infinite[DOF_NAMES.index("right_elbow_x")] = np.inf  # another arm's DOF: the fitted torques were NaN
    left = controller.fit_torque_limits(infinite, state)
    assert left is infinite
    sent = clip_torques(left, limit)  # as Controller.apply sends them
    assert np.all(np.isfinite(sent[arms])) and np.all(np.abs(sent) <= limit)

    def singular(*_: object) -> np.ndarray:
        raise np.linalg.LinAlgError("Singular matrix")

    monkeypatch.setattr(np.linalg, "solve", singular)
    assert controller.fit_torque_limits(tau, state) is tau
    core.close()


def test_same_inputs_same_contacts_bit_for_bit() -> None:
    a = _stroke_contacts("cartesian", [0.25], [3.0], 0.35)
    b = _stroke_contacts("cartesian", [0.25], [3.0], 0.35)
    assert a and [c.model_dump() for c in a] == [c.model_dump() for c in b]


def _tip_rms_mm(control: str) -> float:
    core = PhysicsCore(scene="drummer", control=control)
    scene = _scene(core)
    hit, normal = _snare(core)
    rest = scene.rest_targets["left_hand"]
    # a stroke in the air, turning round smoothly (no head to bounce off)
    ts, ps, vs = strokes_knots(rest, hit + normal * 0.03, normal, [0.45], [1.0], rebound=0.0, contact_s=0.05)
    scene.add_cartesian("left_hand", 0.0, rest, np.zeros(3), 0.0)
    for k in range(len(ts)):
        scene.add_cartesian("left_hand", float(ts[k]), ps[k], vs[k], 0.0)
    errors = []
    i = LIMBS.index("left_hand")
    for k in range(1, 601):
        core.step(k / 1000)
        target = scene.cartesian_targets(k / 1000)["left_hand"][0]
        if k > 300:  # after settling on the rest target
            errors.append(float(np.linalg.norm(scene.body.effector_positions()[i] - target)))
    core.close()
    return 1000 * float(np.sqrt(np.mean(np.square(errors))))


def test_cartesian_tracking_beats_joint_space_tracking_on_a_stroke() -> None:
    cartesian, joint = _tip_rms_mm("cartesian"), _tip_rms_mm("joint_pd")
    assert cartesian < joint
    assert cartesian < 10.0


def test_bad_targets_are_rejected_with_a_clear_error_and_counted() -> None:
    core = PhysicsCore(scene="drummer")
    scene = _scene(core)
    with pytest.raises(TargetError, match="not finite"):
        scene.add_cartesian("right_hand", 0.5, np.array([0.1, np.nan, 1.0]), np.zeros(3), 0.0)
    with pytest.raises(TargetError, match="unreachable"):
        scene.add_cartesian("right_hand", 0.5, np.array([0.0, 3.0, 1.0]), np.zeros(3), 0.0)
    with pytest.raises(TargetError, match="in the past"):
        scene.add_cartesian("right_hand", -1.0, np.array([0.0, 0.4, 1.0]), np.zeros(3), 0.0)
    with pytest.raises(TargetError, match="114 values"):
        scene.add_joints(0.5, np.zeros(57), 0.0)
    with pytest.raises(TargetError, match="non-finite"):
        scene.add_joints(0.5, np.full(114, np.nan), 0.0)
    bad = scene.rest.copy()
    bad[DOF_NAMES.index("right_elbow_x")] = math.radians(-90)
    with pytest.raises(TargetError, match="right_elbow_x"):
        scene.add_joints(0.5, np.concatenate([bad, np.zeros(57)]), 0.0)
    # over the wire: refused, counted, nothing queued, no crash
    far = CartesianTarget(limb="left_hand", time=0.5, x=0.0, y=4.0, z=1.0, vx=0, vy=0, vz=0)
    assert [o.message.ADDRESS for o in core.handle(far, 0.0, "test")] == ["/batteur/physics/rejected"]
    short = JointTarget(time=0.5, values=(0.0,) * 10)
    assert [o.message.ADDRESS for o in core.handle(short, 0.0, "test")] == ["/batteur/physics/rejected"]
    assert core.rejected == {"CartesianTarget": 1, "JointTarget": 1}
    assert core.rejected_total == 2  # what the node's Health reports as dropped
    assert len(scene.limb_tracks["left_hand"]) == 0 and len(scene.joint_track) == 0
    _run(core, 0.0, 0.05)
    core.close()


def test_euler_and_quaternion_limits_are_enforced_in_simulation() -> None:
    core = PhysicsCore(scene="drummer", control="joint_pd")
    scene = _scene(core)
    ctl = scene.controller
    body = scene.body
    # a shoulder pose inside the Euler box but outside the quaternion ellipsoid (Algorithm 1)
    shoulder = JOINTS.index("right_shoulder") * 3
    limit = scene.limits.quaternion["right_shoulder"]
    target = scene.rest.copy()
    best = None
    for x in np.linspace(body.lower[shoulder], body.upper[shoulder], 9):
        for y in np.linspace(body.lower[shoulder + 1], body.upper[shoulder + 1], 9):
            e = np.array([x, y, scene.rest[shoulder + 2]])
            r = float(limit.radius(Rotation.from_euler("XYZ", e[None, :]).as_quat())[0])
            if best is None or r > best[0]:
                best = (r, e)
    assert best is not None and best[0] > 1.3
    target[shoulder:shoulder + 3] = best[1]
    assert ctl.clamp_targets(target)[shoulder:shoulder + 3] != pytest.approx(best[1])  # projected inside
    body.set_state(target)  # start outside: the restoring torque must bring it back
    scene.add_joints(0.001, np.concatenate([target, np.zeros(57)]), 0.0)
    _run(core, 0.0, 0.4)
    theta, _ = body.state()
    radius = float(limit.radius(Rotation.from_euler("XYZ", theta[None, shoulder:shoulder + 3]).as_quat())[0])
    assert radius < 1.1
    assert np.all(theta >= body.lower - 0.03) and np.all(theta <= body.upper + 0.03)  # Euler boxes hold
    core.close()


def test_a_gesture_plan_is_tracked() -> None:
    core = PhysicsCore(scene="drummer")
    scene = _scene(core)
    hit, normal = _snare(core)
    ts, ps, vs = strokes_knots(scene.rest_targets["left_hand"], hit, normal, [0.3], [2.0])
    look_right = HeadTrajectory(np.array([0.0, 1.0]), np.array([[0.6, 0.6, 0.9], [0.6, 0.6, 0.9]]), np.zeros(2))
    plan = GesturePlan(trajectories={Limb.LEFT_HAND: LimbTrajectory(Limb.LEFT_HAND, ts, ps, vs)}, strokes=[],
                       head=look_right, start_time=float(ts[0]), end_time=float(ts[-1]))
    core.load_plan(plan, start_at=float(ts[0]))
    contacts = [c for c in _run(core, 0.0, 0.45) if c.instrument == "snare"]
    assert contacts and abs(contacts[0].time - 0.3) < 0.01
    theta, _ = scene.body.state()
    assert theta[DOF_NAMES.index("neck_z")] < -0.1 and theta[DOF_NAMES.index("head_z")] < -0.1  # turned right
    far = LimbTrajectory(Limb.RIGHT_HAND, np.array([0.0, 1.0]), np.array([[0, 5.0, 1], [0, 5.0, 1]]), np.zeros((2, 3)))
    with pytest.raises(TargetError, match="unreachable"):
        core.load_plan(GesturePlan(trajectories={Limb.RIGHT_HAND: far}, strokes=[]))
    rest = scene.rest_targets["right_hand"]
    rows = np.array([rest, rest, [0.0, 5.0, 1.0], [0.0, 7.0, 1.0]])  # the first bad knot is named, not the worst
    with pytest.raises(TargetError, match=r"\[0.0, 5.0, 1.0\] is unreachable"):
        scene.check_cartesian_rows("right_hand", rows)
    rows[1, 0] = np.nan
    with pytest.raises(TargetError, match="not finite"):
        scene.check_cartesian_rows("right_hand", rows)
    scene.check_cartesian_rows("right_hand", rows[:1])  # reachable rows pass
    core.close()


def test_live_switching_grip_mode_and_reset_keeps_the_drummer_stable() -> None:
    core = PhysicsCore(scene="drummer", control="cartesian")
    scene = _scene(core)
    ks = scene.controller.ks.copy()
    core.handle(PhysicsGains(group="arms", ks_scale=2.0, kd_scale=1.0), 0.0, "test")
    arm = DOF_NAMES.index("right_elbow_x")
    assert scene.controller.ks[arm] == pytest.approx(2 * ks[arm])
    assert scene.controller.ks[DOF_NAMES.index("lumbar_x")] == pytest.approx(ks[DOF_NAMES.index("lumbar_x")])
    core.handle(PhysicsIk(damping=0.05, posture_gain=1.0), 0.0, "test")
    assert scene.controller.params.ik_damping == 0.05 and scene.controller.params.posture_gain == 1.0
    core.handle(PhysicsGrip(hand="both", grip="german"), 0.0, "test")
    assert scene.grip == {"left": "german", "right": "german"}
    elbow_z = DOF_NAMES.index("right_elbow_z")
    assert scene.rest[elbow_z] == pytest.approx(math.radians(80))
    _run(core, 0.0, 0.1)
    core.handle(PhysicsControlMode(mode="joint_pd"), 0.1, "test")
    _run(core, 0.1, 0.2)
    core.handle(PhysicsControlMode(mode="joint_spd"), 0.2, "test")  # the stable PD needs no floating base
    assert scene.controller.mode == "joint_spd" and core.settings.control == "joint_spd"
    _run(core, 0.2, 0.22)
    assert not core.rejected
    core.handle(PhysicsReset(time=0.22), 0.22, "test")
    core.handle(PhysicsControlMode(mode="cartesian"), 0.22, "test")
    _run(core, 0.22, 0.3)
    theta, theta_dot = scene.body.state()
    assert np.all(np.isfinite(theta)) and np.all(np.isfinite(theta_dot))
    core.close()


def test_joint_spd_tracks_like_the_explicit_pd_and_is_deterministic() -> None:
    """The stable PD on the default fixed base: the joint-space stroke within 2 mm RMS of the explicit PD's, and
    the same run twice gives the same state bit for bit (PyBullet's STABLE_PD_CONTROL, used before, gave a
    different state nearly every run and now and then NaN)."""
    explicit, stable = _tip_rms_mm("joint_pd"), _tip_rms_mm("joint_spd")
    assert abs(stable - explicit) < 2.0, (stable, explicit)
    runs = []
    for _ in range(2):
        core = PhysicsCore(scene="drummer", control="joint_spd")
        scene = _scene(core)
        assert not scene.body.floating_base
        hit, normal = _snare(core)
        ts, ps, vs = strokes_knots(scene.rest_targets["left_hand"], hit, normal, [0.3], [2.0])
        for k in range(len(ts)):
            scene.add_cartesian("left_hand", float(ts[k]), ps[k], vs[k], 0.0)
        states = []
        for k in range(1, 401):
            core.step(k / 1000)
            if k % 10 == 0:
                states.append(np.concatenate(scene.body.state()))
        runs.append(np.array(states))
        core.close()
    assert np.all(np.isfinite(runs[0])) and np.array_equal(runs[0], runs[1])


def test_a_floating_base_stays_pinned_to_the_throne() -> None:
    core = PhysicsCore(scene="drummer", control="joint_spd", floating_base=True)
    scene = _scene(core)
    assert scene.body.floating_base and len(scene.body.pins) == 1  # the trunk; the legs keep fixed bases
    bases = [core.world.client.getBasePositionAndOrientation(body)[0] for body in scene.body.ids]
    _run(core, 0.0, 0.05)
    for body, base in zip(scene.body.ids, bases, strict=True):
        assert np.allclose(core.world.client.getBasePositionAndOrientation(body)[0], base, atol=1e-3)
    core.close()


def test_a_captured_posture_in_the_null_space_keeps_the_arm_configuration() -> None:
    """Algorithm 2's posture term: with the same tip targets, the IK follows a posture track (here: the posture
    whose tips the targets are) instead of drifting toward the rest posture."""
    errors = {}
    for with_posture in (False, True):
        core = PhysicsCore(scene="drummer", control="cartesian")
        scene = _scene(core)
        posture = scene.rest.copy()
        for dof, delta in (("right_shoulder_y", -0.25), ("right_elbow_z", 0.5), ("right_shoulder_z", 0.3)):
            posture[DOF_NAMES.index(dof)] += delta
        kin = scene._kinematic()
        kin.set_state(posture)
        tip = kin.kinematics()[0][LIMBS.index("right_hand")] - scene.target_offset["right_hand"]
        scene.add_cartesian("right_hand", 0.0, scene.rest_targets["right_hand"], np.zeros(3), 0.0)
        scene.add_cartesian("right_hand", 0.4, tip, np.zeros(3), 0.0)
        if with_posture:
            scene.add_posture(0.0, np.concatenate([scene.rest, np.zeros(57)]), 0.0)
            scene.add_posture(0.4, np.concatenate([posture, np.zeros(57)]), 0.0)
        _run(core, 0.0, 0.9)
        theta, _ = scene.body.state()
        arm = [i for i, n in enumerate(DOF_NAMES) if n.startswith(("right_shoulder", "right_elbow"))]
        errors[with_posture] = float(np.sqrt(np.mean((theta[arm] - posture[arm]) ** 2)))
        target = scene.cartesian_targets(0.9)["right_hand"][0]
        assert np.linalg.norm(scene.body.effector_positions(actual=False)[LIMBS.index("right_hand")] - target) < 0.01
        with pytest.raises(TargetError, match="114 values"):
            scene.add_posture(1.0, np.zeros(57), 0.9)
        with pytest.raises(TargetError, match="non-finite"):
            scene.add_posture(1.0, np.full(114, np.nan), 0.9)
        core.close()
    assert errors[True] < 0.5 * errors[False], errors


def test_poses_skeleton_and_a_left_handed_kit() -> None:
    core = PhysicsCore(scene="drummer", left_handed=True, pose_rate_hz=60.0)
    scene = _scene(core)
    assert core.kit.handedness == "left"
    assert "right_hand" in scene.rest_targets and scene.rest_targets["right_hand"][0] > 0  # snare on the right
    out = core.step(0.0) + core.step(0.001)
    skeleton = next(o.message for o in out if isinstance(o.message, Skeleton))
    pose = next(o.message for o in out if isinstance(o.message, Pose))
    assert {"pelvis", "head", "left_stick", "right_foot", "kit.snare"} <= set(skeleton.names)
    assert len(pose.values) == 7 * len(skeleton.names) and pose.layout == skeleton.layout
    core.close()
    default = load_kit("default")
    assert default.handedness == "right"


def test_double_pedal_left_footboard_drives_its_own_beater_into_the_kick() -> None:
    core = PhysicsCore(scene="drummer", kit="double_pedal")
    scene = _scene(core)
    kb = scene.kit_bodies
    assert "kick_beater_left" in kb.strikers.values()
    pedal = kb.pedals[core.kit.left_bass_pedal or ""]
    c = core.world.client
    parts = set()
    for k in range(1, 201):
        toe, _ = core.world.link_frame(pedal.body, pedal.footboard_link)
        c.applyExternalForce(pedal.body, pedal.footboard_link, [0.0, 0.0, -300.0],
                             (toe + np.array([0.0, 0.2, 0.0])).tolist(), p.WORLD_FRAME)
        parts |= {o.message.part for o in core.step(k / 1000)
                  if isinstance(o.message, Contact) and o.message.instrument == "kick"}
    assert "kick_beater_left" in parts
    core.close()


@pytest.mark.parametrize("press, sounds", [(0.975, True), (0.9, False)])
def test_a_kick_pedal_pressed_slowly_sounds_only_near_the_end_of_its_travel(press: float, sounds: bool) -> None:
    """A soft kick follows the footboard without overshooting the beater's gear: pressed steadily to where a foot
    holds it (about 0.98 of the travel, common.kit.FOOT_PRESS_TABLE) the beater must still reach the head;
    half-way it must not."""
    from services.physics.kitbodies import PEDAL_REST_ANGLE

    core = PhysicsCore(scene="drummer")
    pedal = _scene(core).kit_bodies.pedals["kick_pedal"]
    c = core.world.client
    beaters = []
    for k in range(1, 401):  # the footboard driven down over 0.3 s (a soft stroke), then held
        s = min(k / 300, 1.0)
        c.setJointMotorControl2(pedal.body, pedal.footboard_joint, p.POSITION_CONTROL,
                                targetPosition=PEDAL_REST_ANGLE * (1.0 - press * s), force=400.0)
        beaters += [o.message for o in core.step(k / 1000)
                    if isinstance(o.message, Contact) and o.message.part == "kick_beater"]
    assert bool(beaters) == sounds, [(round(b.time, 3), round(b.normal_velocity, 3)) for b in beaters]
    core.close()


def test_a_live_change_of_the_contact_softening_reaches_the_touching_arm_only() -> None:
    core = PhysicsCore(scene="drummer", control="cartesian")
    controller = _scene(core).controller
    theta, theta_dot = _scene(core).body.state()
    target = theta + 0.05  # a PD error on every DOF, so the softening shows in the torques

    def torques(softening: float, touching: set[str]) -> np.ndarray:
        controller.set_params(dataclasses.replace(controller.params, contact_softening=softening))
        controller.touching = touching
        return controller.computed_torque(theta, theta_dot, target, np.zeros_like(theta), np.zeros_like(theta))

    free = torques(0.5, set())
    soft = torques(0.5, {"right_hand"})
    softer = torques(0.25, {"right_hand"})  # the same contact, the parameter changed live
    # the arm's chain (spine included) is softened, which the whole trunk feels; the legs are bodies of their own
    legs = np.array([name.split("_")[1] in ("hip", "knee", "ankle") for name in DOF_NAMES])
    assert legs.sum() == 18
    assert np.any(soft[~legs] != free[~legs]) and np.all(soft[legs] == free[legs])
    assert np.any(softer[~legs] != soft[~legs]) and np.all(softer[legs] == soft[legs])
    np.testing.assert_array_equal(torques(0.5, {"right_hand"}), soft)  # and back
    core.close()


def test_a_diverged_simulation_is_reset_counted_and_keeps_stepping() -> None:
    """A non-finite state (here poked into a spine joint) must not leave every later step failing: the core
    resets the drummer to its rest posture, counts it, and goes on sending poses."""
    core = PhysicsCore(scene="drummer")
    scene = _scene(core)
    _run(core, 0.0, 0.01)
    trunk = scene.body.parts[0]
    core.world.client.resetJointState(trunk.id, trunk.state_joints[5], float("nan"), 0.0)
    assert not core.world.finite_state()
    poses = [o.message for k in range(11, 201) for o in core.step(k / 1000) if isinstance(o.message, Pose)]
    assert core.diverged == 1 and core.world.finite_state() and core.world.steps == 200
    assert len(poses) >= 10 and all(math.isfinite(v) for v in poses[-1].values)
    theta, _ = scene.body.state()
    assert np.allclose(theta, scene.rest, atol=0.05)  # back near the rest posture it was reset to
    core.close()


def _arm_sag_rad(compensate: bool) -> float:
    """Largest error (rad) of the arms' DOF (clavicles to wrists) from the rest posture after 0.5 s of joint_pd
    holding it (the feet, on the pedals, are held by their contacts as much as by the PD)."""
    arms = [i for i, name in enumerate(DOF_NAMES) if name.split("_")[1] in ("clavicle", "shoulder", "elbow", "wrist")]
    assert len(arms) == 24
    core = PhysicsCore(scene="drummer", control="joint_pd")
    controller = _scene(core).controller
    controller.params = dataclasses.replace(controller.params, gravity_compensation=compensate)
    _run(core, 0.0, 0.5)
    theta, _ = _scene(core).body.state()
    core.close()
    return float(np.abs(theta - controller.rest)[arms].max())


def test_gravity_compensation_holds_the_resting_arms() -> None:
    """joint_pd's gravity term (the inverse dynamics at rest of the body's trees) holds the arms where the PD
    alone lets them sag (by about 0.01 rad at the shoulders)."""
    held, sagging = _arm_sag_rad(True), _arm_sag_rad(False)
    assert held < 1e-3 and sagging > 5e-3, (held, sagging)
