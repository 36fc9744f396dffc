"""Controllers: joint-space PD (explicit, stable, computed torque) and Cartesian DLS IK (Algorithm 2).

Modes: ``joint_pd`` (explicit PD below), ``joint_spd`` (the stable PD of Tan, Liu and Turk,
:meth:`Controller.stable_pd`), ``joint_ct`` (the PD through inverse
dynamics, :meth:`Controller.computed_torque`), ``cartesian`` (Algorithm 2
feeding ``joint_ct``) and ``cartesian_pd`` (Algorithm 2 feeding ``joint_pd``).

Joint space (the paper's tracking): ``tau = ks (theta_t - theta) + kd (theta_dot_t - theta_dot)
+ tau_g``, with target velocities, gravity compensation ``tau_g`` (the torque
that holds every subtree against gravity), within per-joint torque limits (in the computed-torque
modes an arm's or the trunk's DOF over its limit is fitted to it, the others keeping their accelerations:
:meth:`Controller.fit_torque_limits`; the rest clipped joint by joint).
Gains per DOF: ``ks = M_jj w^2``, ``kd = 2 zeta w M_jj`` with ``M_jj`` the
joint-space inertia at the rest posture, so every joint has the same natural
frequency ``w``.

Cartesian (Algorithm 2): at every step, for the limbs with a target, the
stacked effector Jacobian ``J`` (3 per limb x 57) gives, with the damped
least-squares (singularity-robust) inverse weighted by the joint inertias,
``J+ = W^-1 J^T (J W^-1 J^T + lambda^2 I)^-1``,

    theta_dot_ref = J+ (v_t + K (x_t - x)) + (I - J+ J) a (theta_rest - theta_ref)
    theta_ref += theta_dot_ref dt

clamped to the joint limits; the PD then tracks ``theta_ref, theta_dot_ref``
(see :meth:`Controller.ik_targets`).

Joint limits: the Euler boxes are the revolute joints' own limits (PyBullet
enforces them); the quaternion ellipsoids (Algorithm 1) are enforced here,
by projecting targets inside and by a restoring torque on a joint that
leaves its ellipsoid.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from itertools import chain

import numpy as np

from common.quiet_pybullet import pybullet as p
from services.physics.body import LIMBS, Body, consecutive_runs
from services.physics.character import JOINT_GROUP, JOINTS, joint_kind
from services.physics.kernels import (
    clip_torques,
    computed_torque_state,
    dls_reference,
    enforce_limits,
    held_torque,
    inverse_dynamics,
    project_into_ellipsoids,
)
from services.physics.limits import JointLimits
from services.physics.urdf import load_robot
from services.physics.world import World, WorldSettings

# ---------------------------------------------------------------------- settings

KD_CAP = 0.7

COMPUTED_TORQUE_MODES = ("joint_ct", "cartesian")
"""Modes whose PD goes through inverse dynamics; joint_pd and cartesian_pd use the explicit diagonal PD."""
"""Explicit damping stays below KD_CAP * I_free / dt (measured: 1.5 slowly destabilises the arms at 1 ms)."""

MASS_REFRESH_S = 0.03
"""Computed-torque modes with updates held over several steps: the joint-space mass matrix used between updates
is recomputed at least this often, seconds of simulation (it costs about 100 us, 25 times the inverse dynamics,
and only scales the small correction between updates; the update itself is exact inverse dynamics)."""

SATURATION_ROUNDS = 4
"""Computed-torque modes: rounds of :meth:`Controller.fit_torque_limits` (a round adds the DOF the last one's
correction took over their limits; what is over after the last is clipped)."""

TRUNK_IK_WEIGHT = 0.1
"""Inverse DLS weight of the lumbar and thoracic DOF (0: they keep the posture; 1: as free as the arms)."""

LEG_POSTURE_BAND_RAD = math.radians(18.0)
"""A leg DOF's reference may wander this far (rad) from its null-space posture under the plain ``posture_gain``;
beyond it :data:`LEG_POSTURE_GAIN` pulls the excess back. Under fast kicks the footboard pushes the foot toe up at
every stroke (the reference follows the state while the foot presses it) and the DLS brings the foot down mostly by
the ankle: at 2 1/s the leg drifted stroke by stroke (16ths at 180 bpm: the ankle 14 -> 47 degrees, the hip
90 -> 64, the knee -126 -> -105 at the kicks) and the same foot height pressed the board less, the kicks 20 ms
late. Eighths swing the ankle up to 25 degrees from it within a stroke and settle 15 degrees off: a stronger pull
on the whole deviation (4 1/s more) made every Groove file's kicks 6 ms early, a 14-degree band lowered their kick
velocity Spearman 0.895 -> 0.880 (docs/physics.md, "Kicks")."""
LEG_POSTURE_GAIN = 30.0
"""Null-space pull (1/s) on a leg DOF's deviation beyond :data:`LEG_POSTURE_BAND_RAD`, on top of ``posture_gain``."""


@dataclass
class ControlParams:
    """Live-tunable controller parameters.

    ``frequency_hz``/``damping_ratio``: PD natural frequency and damping;
    ``ik_damping``: DLS lambda (metres); ``posture_gain``: null-space pull
    toward the rest posture (1/s); ``task_gain`` / ``task_gain_pd``: Cartesian
    error feedback (1/s) with the computed-torque / the explicit PD;
    ``gravity_compensation``: add tau_g; ``max_joint_speed``: the IK's joint velocity reference is scaled
    down to at most this (rad/s), a guard near singular (stretched) arm configurations.
    ``ct_frequency_hz``: the computed-torque PD's natural frequency; ``trunk_ct_frequency_hz``: the same for
    the seat, lumbar and thoracic DOF (the damping ratio is kept). About the seat's and lumbar's horizontal
    axes the upper body weighs 5-12 kg m^2 and gets 250-400 N m, a few tens of rad/s^2; a 15 Hz PD asked it
    for hundreds after strokes, and clipped joint by joint those demands set the pelvis and spine chattering
    between their torque limits (docs/physics.md, "The trunk's gains").
    """

    frequency_hz: float = 25.0
    damping_ratio: float = 1.0
    ik_damping: float = 0.02
    posture_gain: float = 2.0
    task_gain: float = 100.0
    task_gain_pd: float = 50.0
    gravity_compensation: bool = True
    limit_stiffness_scale: float = 2.0
    ct_frequency_hz: float = 15.0
    trunk_ct_frequency_hz: float = 10.6
    max_lead_rad: float = 0.1
    contact_lead_rad: float = 0.005
    contact_softening: float = 1.0
    max_ff_accel: float = 300.0
    max_joint_speed: float = 20.0


class Controller:
    """Computes and applies the joint torques of one step for the chosen mode."""

    def __init__(self, world: World, body: Body, limits: JointLimits, rest: np.ndarray,
                 params: ControlParams | None = None) -> None:
        self.world = world
        self.body = body
        self.limits = limits
        self.params = params or ControlParams()
        self.rest = rest.copy()
        self.mode = "cartesian"
        self.control_dt = world.dt
        """Seconds between two full control updates (IK, inverse dynamics, limits); between them
        :meth:`apply_between` corrects the held torques at every physics step (see :meth:`apply`)."""
        self._held: _HeldTorques | None = None
        self._ct_mass: np.ndarray | None = None
        self._mass_age = 0.0
        c = world.client
        n = len(body.dof_list)
        # joint-space inertia at the rest posture, part by part (a floating base: 6 base DOF first, then its joints)
        body.set_state(rest)
        self.inertia_locked = np.zeros(n)
        self.inertia = np.zeros(n)
        dof_of = {j: k for k, j in enumerate(body.dof_list)}
        for part in body.parts:
            q_all = [c.getJointState(part.id, j)[0] for j in part.movable]
            base: list[float] = []
            if body.floating_base:
                base_pos, base_quat = c.getBasePositionAndOrientation(part.id)
                base = [*base_pos, *base_quat]
            mass = np.asarray(c.calculateMassMatrix(part.id, [*base, *q_all]))
            offset = mass.shape[0] - len(part.movable)
            # effective inertia of each DOF with every other joint free: 1 / (M^-1)_jj. The diagonal of M itself
            # (others locked) overestimates it for short links between co-linear DOF (clavicle-shoulder,
            # neck-head), whose explicit PD then goes unstable at a 1 ms step
            inv = np.linalg.inv(mass)
            for k, j in enumerate(part.movable):
                dof = dof_of.get(part.offset + j)
                if dof is not None:
                    self.inertia_locked[dof] = mass[offset + k, offset + k]
                    self.inertia[dof] = max(1.0 / inv[offset + k, offset + k], 1e-4)
        names = body.model.dof_names
        self.ik_weight_inv = np.array([0.0 if n_.split("_")[0] == "seat" or "clavicle" in n_
                                       else TRUNK_IK_WEIGHT if n_.split("_")[0] in ("lumbar", "thoracic")
                                       else 1.0 for n_ in names])
        """Per-DOF inverse weights of the DLS (1: plain DLS as Algorithm 2; 0: the DOF keeps its posture).
        The seat and shoulder girdles hold the posture; the trunk helps a little (``TRUNK_IK_WEIGHT``) so an arm
        reaching a far drum is not stretched into its elbow limit (a singular, unstable configuration); the limbs
        reach."""
        self.scale_ks = np.ones(n)
        self.scale_kd = np.ones(n)
        self.group_of = np.array([JOINT_GROUP[joint_kind(name.rsplit("_", 1)[0])] for name in body.model.dof_names])
        self._update_gains()
        # quaternion-limited joints: DOF index triples
        self.q_joints = [j for j in JOINTS if j in limits.quaternion]
        self.q_index = np.array([[JOINTS.index(j) * 3 + k for k in range(3)] for j in self.q_joints], dtype=int)
        if self.q_joints:
            self.q_mean_inv = np.array([_conj(limits.quaternion[j].mean) for j in self.q_joints])
            self.q_mean = np.array([limits.quaternion[j].mean for j in self.q_joints])
            self.q_axes = np.array([limits.quaternion[j].axes for j in self.q_joints])
            self.q_extents = np.array([limits.quaternion[j].extents for j in self.q_joints])
        self.limit_violations = 0
        """Quaternion-limited joints whose state was outside their ellipsoid (so got a restoring torque), summed
        over the full control updates: one joint outside for 10 updates counts 10 (``--control-rate-hz`` 1000:
        one update per physics step)."""
        self.torque_saturated = 0
        """DOF whose torque was clipped to its limit (``Body.torque_limit``), summed over the physics steps (full
        updates and the steps between): one DOF at its limit for 10 steps counts 10."""
        self.last_tau = np.zeros(n)
        self.theta_ref: np.ndarray | None = None
        self._id: tuple[World, list[tuple[int, np.ndarray]]] | None = None
        self._last_theta_dot_t: np.ndarray | None = None
        self.touching: set[str] = set()
        """Limbs whose stick touches an instrument at the last step (set by the scene before apply)."""
        self.posture_rate: np.ndarray | None = None
        """Rates (57,) rad/s of a moving null-space posture (``rest``), fed forward by the IK; None: still."""
        self._no_rate = np.zeros(n)
        self._no_mass = np.zeros((0, 0))
        self._no_softening = np.ones(n)
        self._softening: tuple[float, dict[frozenset[str], np.ndarray]] = (math.nan, {})
        """contact_softening and, for it, touching limbs -> the grip softening per DOF (57,), built once per set."""
        self.leg_dof = np.flatnonzero([name.split("_")[1] in ("hip", "knee", "ankle") for name in names])
        """The legs' DOF (hips, knees, ankles): their posture is held within :data:`LEG_POSTURE_BAND_RAD`."""
        self._rows: dict[tuple[str, ...], np.ndarray] = {}
        """Limbs with targets -> their rows in LIMBS (int64), for the IK kernel."""
        self.fit_dof = np.array([name.split("_")[0] in ("seat", "lumbar", "thoracic")
                                 or name.split("_")[1] in ("clavicle", "shoulder", "elbow", "wrist")
                                 for name in body.model.dof_names])
        """DOF (57,) whose torques over their limits :meth:`fit_torque_limits` fits: the trunk (seat, lumbar,
        thoracic) and the arms, clavicles to wrists; the head and legs are clipped joint by joint. The trunk clipped
        joint by joint spun the light pelvis between the seat's and the lumbar's torques, which no longer balanced
        on it: at a stroke's rebound the IK's trunk share reverses in a few milliseconds, the PD asks the trunk for
        thousands of N m, and the pelvis turned at 1,300 deg/s at every loud backbeat, 2,500 deg/s on a hard
        floor-tom stroke, into the seat's 30-degree yaw limit (docs/physics.md, "The trunk's torque limits").
        (The legs fitted too: loud snare contacts as short, but the velocity Spearman within each sound 0.885 ->
        0.860 and the p95 timing error 5.2 -> 6.2 ms on five Groove files.)"""
        self._ct_state: np.ndarray | None = None
        """The last :meth:`computed_torque`'s inverse-dynamics input (3, n + P): angles, rates, accelerations."""
        self._ensure_id_model()  # here, not at the first step of a computed-torque mode: a live step must not wait

    def _update_gains(self) -> None:
        """ks = I w^2, kd = 2 zeta w I with I the DOF's inertia with every other joint free.

        That inertia (1 / (M^-1)_jj) is what one joint's PD actually moves in the fastest mode of the chain
        (a light clavicle between the thorax and the arm, the neck between thorax and head); gains from the
        locked-chain inertia M_jj drive those modes unstable at a 1 ms step. Gravity compensation carries
        the static load, so moderate gains still hold the posture.
        """
        w = 2 * math.pi * self.params.frequency_hz
        zeta = self.params.damping_ratio
        self.ks = self.inertia * w * w * self.scale_ks
        # damping for the slow mode too (the joint moving its whole subtree, inertia M_jj), capped where an
        # explicit damper on the fast mode (inertia I_free) stays stable
        kd_slow = 2 * zeta * np.sqrt(self.ks * self.inertia_locked)
        kd_cap = KD_CAP * self.inertia / self.world.dt
        # a live scale above 1 may not take the damper past that cap either (kd_scale 1.5 shook the body)
        self.kd = np.minimum(np.minimum(np.maximum(2 * zeta * w * self.inertia, kd_slow), kd_cap) * self.scale_kd,
                             kd_cap)
        ratio = np.where(self.group_of == "trunk", self.params.trunk_ct_frequency_hz / self.params.ct_frequency_hz,
                         1.0)
        self.ct_ks = self.scale_ks * ratio * ratio
        self.ct_kd = self.scale_kd * ratio
        """The computed-torque PD's per-DOF scales of ``w^2`` and ``2 zeta w`` (the live scales and the trunk's
        lower frequency)."""

    def set_gains(self, group: str, ks_scale: float, kd_scale: float) -> None:
        mask = np.ones(len(self.ks), dtype=bool) if group == "all" else self.group_of == group
        self.scale_ks[mask] = ks_scale
        self.scale_kd[mask] = kd_scale
        self._update_gains()

    def set_params(self, params: ControlParams) -> None:
        self.params = params
        self._update_gains()

    # ------------------------------------------------------------------ limits

    def clamp_targets(self, theta: np.ndarray) -> np.ndarray:
        """Targets inside the Euler boxes and the quaternion ellipsoids."""
        out = np.clip(theta, self.body.lower, self.body.upper)
        if self.q_joints:
            e = out[self.q_index]
            proj, outside = self._project(e)
            if np.any(outside):
                out[self.q_index[outside]] = proj[outside]
                out = np.clip(out, self.body.lower, self.body.upper)
        return out

    def _project(self, e: np.ndarray, repeat: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """Project Euler triples (repeat * K, 3) of the limited joints into their ellipsoids."""
        return project_into_ellipsoids(np.ascontiguousarray(e, dtype=float), self.q_mean_inv, self.q_mean,
                                       self.q_axes, self.q_extents)

    def limit_torque(self, theta: np.ndarray) -> np.ndarray:
        """Restoring torque (57,) for joints outside their quaternion ellipsoid."""
        return self.enforce_limits(theta, np.clip(theta, self.body.lower, self.body.upper))[1]

    def enforce_limits(self, theta: np.ndarray, theta_t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(targets clipped to the Euler boxes and projected into the quaternion ellipsoids (57,), restoring torque
        for the state (57,)); :func:`kernels.enforce_limits`."""
        if not self.q_joints:
            return np.clip(theta_t, self.body.lower, self.body.upper), np.zeros_like(theta)
        out, tau, violations = enforce_limits(theta, theta_t, self.q_index, self.q_mean_inv, self.q_mean, self.q_axes,
                                              self.q_extents, self.ks, self.params.limit_stiffness_scale,
                                              self.body.lower, self.body.upper)
        self.limit_violations += violations
        return out, tau

    # ------------------------------------------------------------------ gravity

    def gravity_torque(self, theta: np.ndarray, passive: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """Joint torques (n,) N m that hold every subtree against gravity at the angles ``theta`` (n,) rad: the
        inverse dynamics at rest of the body's fixed-base trees (:func:`kernels.inverse_dynamics`, as the
        computed-torque modes use it; no read of every link's state). ``passive``: the fulcrums' angles and
        velocities if already read (the sticks hang from them)."""
        pq, _ = self.body.passive_state() if passive is None else passive
        return self._bias_torque(theta, np.zeros_like(theta), (pq, np.zeros_like(pq)))

    def _bias_torque(self, theta: np.ndarray, theta_dot: np.ndarray,
                     passive: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
        """``C(q, qd) + g(q)``, joint torques (n,) N m: the inverse dynamics at zero acceleration of the body's
        fixed-base trees at the angles ``theta`` (n,) rad and rates ``theta_dot`` (n,) rad/s, the passive joints
        (the fulcrums) at ``passive`` (angles rad, rates rad/s)."""
        self._ensure_id_model()
        n = len(theta)
        pq, pqd = passive
        state = np.zeros((3, n + len(pq)))
        state[0, :n], state[1, :n] = theta, theta_dot
        state[0, n:], state[1, n:] = pq, pqd
        return inverse_dynamics(state, *self._id_tree, self.world.settings.gravity)[:n]  # type: ignore[call-arg]

    # ------------------------------------------------------------------ Cartesian (Algorithm 2)

    def reset_reference(self) -> None:
        """Forget the integrated Cartesian reference and the held torques (after a reset or a mode switch)."""
        self.theta_ref = None
        self._held = None
        self._ct_mass = None

    def ik_targets(self, theta: np.ndarray, targets: dict[str, tuple[np.ndarray, np.ndarray]],
                   touching: set[str] | frozenset[str] = frozenset()) -> tuple[np.ndarray, np.ndarray]:
        """theta_t (57,), theta_dot_t (57,) from Cartesian targets {limb: (position (3,), velocity (3,))}.

        The reference integrates the DLS joint velocity that drives the actual effectors onto their
        targets: ``x_dot_c = v_t + K (x_t - x)``, ``theta_dot_ref = J+ x_dot_c + (I - J+ J) a (theta_rest -
        theta_ref)``, ``theta_ref += theta_dot_ref dt``; the error feedback on the *actual* effector makes it
        integrate away the PD's lag (Algorithm 2 with the correction accumulated rather than re-applied).
        While a limb touches something (``touching``: a stick on an instrument, a foot on a footboard) and its
        target is below it, its error is not integrated and the reference may barely lead the state: the
        surface stops the limb where the plan goes through, and winding up would press it in.
        """
        eff = self.body.effector_pos
        limbs = tuple(limb for limb in LIMBS if limb in targets)
        if self.theta_ref is None:
            self.theta_ref = theta.copy()
        if not limbs:
            self.theta_ref = self.rest.copy()
            return self.rest.copy(), np.zeros_like(theta)
        rows = self._rows.get(limbs)
        if rows is None:
            rows = self._rows[limbs] = np.array([LIMBS.index(limb) for limb in limbs], dtype=np.int64)
        target_pos = np.array([targets[limb][0] for limb in limbs])
        # a touching limb whose target is below it would only push into the surface: hold its error
        pressing = np.array([limb in touching and targets[limb][0][2] < eff[row, 2]
                             for limb, row in zip(limbs, rows, strict=True)], dtype=np.bool_)
        gain = self.params.task_gain if self.mode in COMPUTED_TORQUE_MODES else self.params.task_gain_pd
        rate = self.posture_rate if self.posture_rate is not None else self._no_rate
        rate = leg_posture_rate(rate, self.rest, self.theta_ref, self.leg_dof)
        new_ref, qdot = dls_reference(
            theta, self.theta_ref, self.rest, rate, eff, self.body.dof_pos, self.body.dof_axes, self.body.chain_mask,
            rows, target_pos, np.array([targets[limb][1] for limb in limbs]), pressing, self.ik_weight_inv,
            self.params.ik_damping,
            gain, self.params.posture_gain, self.control_dt, self.params.max_joint_speed, self.params.max_lead_rad,
            self.params.contact_lead_rad, self.body.lower, self.body.upper)
        self.theta_ref = new_ref
        return new_ref, qdot

    # ------------------------------------------------------------------ apply

    def close(self) -> None:
        if self._id is not None:
            self._id[0].close()
            self._id = None

    def _ensure_id_model(self) -> None:
        """Fixed-base copies of the body's parts in their own client, for their mass matrices (the held updates'
        correction): (world, [(copy's body id, the state slots of its revolute joints in its own order)]); and the
        body's trees for the inverse dynamics (:func:`kernels.inverse_dynamics`, one call for the three parts:
        PyBullet's, through the copies, took three calls and their list conversions, about 25 us an update)."""
        if self._id is not None:
            return
        world = World(WorldSettings(timestep_s=self.world.dt))
        world.client.setGravity(0.0, 0.0, -self.world.settings.gravity)
        slot_of = {j: k for k, j in enumerate(self.body.state_joints)}
        copies: list[tuple[int, np.ndarray]] = []
        for spec, part in zip(self.body.model.parts, self.body.parts, strict=True):
            body_id = load_robot(world.client, spec.robot, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0),
                                 fixed_base=True, flags=p.URDF_USE_INERTIA_FROM_FILE)
            copies.append((body_id, np.array([slot_of[part.offset + j] for j in part.movable], dtype=int)))
        self._id = (world, copies)
        self._id_tree = self.body.dynamics_tree()
        """The body's trees for :func:`kernels.inverse_dynamics` (the copies give the mass matrix)."""
        self._id_order = (np.concatenate([slots for _, slots in copies]),
                          consecutive_runs([len(slots) for _, slots in copies]))
        """The copies' slots one after another, and each copy's (start, stop) in that order."""

    def computed_torque(self, theta: np.ndarray, theta_dot: np.ndarray, theta_t: np.ndarray,
                        theta_dot_t: np.ndarray, last_theta_dot_t: np.ndarray,
                        passive: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """tau = M(q) (qdd_ff + w^2 (q_t - q) + 2 zeta w (qd_t - qd)) + C(q, qd) + g(q): a PD whose gains are
        scaled by the body's own inertia (inverse dynamics of its fixed-base trees; the bases do not move). The
        feed-forward ``qdd_ff`` is the target rate's change since the last update, ``last_theta_dot_t``
        (rad/s), over the control period, within ``max_ff_accel``.

        ``passive``: the fulcrum angles and velocities (rad, rad/s) if already read. With updates held over
        several steps, ``M(q)`` for the correction between updates is refreshed every ``MASS_REFRESH_S``
        (the posture changes little in that time)."""
        self._ensure_id_model()
        assert self._id is not None
        world, copies = self._id
        n = len(theta)
        soft = self._no_softening
        if self.touching:
            value, by_limbs = self._softening
            if value != self.params.contact_softening:  # a live change of the parameter: build them again
                value, by_limbs = self._softening = (self.params.contact_softening, {})
            key = frozenset(self.touching)
            cached = by_limbs.get(key)
            if cached is None:
                cached = by_limbs[key] = np.ones(n)
                for limb in self.touching:  # a relaxed grip while the stick is on a head
                    cached[self.body.chain_mask[LIMBS.index(limb)]] = self.params.contact_softening
            soft = cached
        pq, pqd = self.body.passive_state() if passive is None else passive
        # rows q, qd, qdd in state order: the 57 DOF then the passive joints (not driven: accelerations 0)
        state = computed_torque_state(theta, theta_dot, theta_t, theta_dot_t, last_theta_dot_t, self.control_dt,
                                      self.params.max_ff_accel, soft, self.ct_ks, self.ct_kd,
                                      2 * math.pi * self.params.ct_frequency_hz, self.params.damping_ratio, pq, pqd)
        refresh = self.control_dt > self.world.dt  # held between updates: keep M(q) for the PD's correction
        if refresh:
            self._mass_age += self.control_dt
            refresh = self._ct_mass is None or self._mass_age >= MASS_REFRESH_S - 1e-9
        if refresh:
            self._ct_mass = self._mass_matrix(state[0], n)
            self._mass_age = 0.0
        self._ct_state = state
        tau = inverse_dynamics(state, *self._id_tree, self.world.settings.gravity)  # type: ignore[call-arg]
        return tau[:n]

    def fit_torque_limits(self, tau: np.ndarray, state: np.ndarray) -> np.ndarray:
        """Torques (n,) N m within ``Body.torque_limit``: ``tau`` (n,) N m, the inverse dynamics of ``state`` (its
        input (3, n + P): angles rad, rates rad/s, commanded accelerations rad/s^2) plus torques outside it (the
        limits' restoring torque), with every DOF of :attr:`fit_dof` over its limit held at it and given the
        acceleration that limit leaves it, every other DOF keeping its commanded acceleration (a DOF outside
        :attr:`fit_dof` may stay over its limit: the caller clips). ``tau`` itself when none is over.

        Clipped joint by joint instead, the other DOF would keep torques computed for an acceleration of the
        clipped one that does not happen: a shoulder at its limit after a loud stroke, the elbow's and wrist's
        torques for a deceleration of the upper arm spun the forearm and hand, which stopped late and pressed the
        stick on the head for 10-25 ms (docs/physics.md, "Contact durations in the drummer scene"). The torques
        are linear in the accelerations, ``tau = M qdd + h``: with ``S`` the fitted DOF over their limits,
        ``M_SS d_S = +-limit_S - tau_S`` and ``tau + M[:, S] d_S``, the columns ``M[:, S]`` from one inverse
        dynamics each. A DOF that correction takes over its limit joins ``S`` (``SATURATION_ROUNDS``); whatever is
        over after them the caller clips. ``tau`` itself, for the caller to clip, when a torque over its limit is not
        finite or ``M_SS`` is singular."""
        limit = self.body.torque_limit
        over = (np.abs(tau) > limit) & self.fit_dof
        if not over.any() or not np.isfinite(tau[over]).all():  # inf - inf: every fitted torque NaN; caller clips
            return tau
        n = len(tau)
        gravity = self.world.settings.gravity
        base = inverse_dynamics(state, *self._id_tree, gravity)[:n]  # type: ignore[call-arg]
        probe = state.copy()
        sat = np.flatnonzero(over)
        bound = np.copysign(limit, tau)
        columns = np.empty((n, 0))
        out = tau
        for _ in range(SATURATION_ROUNDS):
            new = sat[columns.shape[1]:]
            added = np.empty((n, len(new)))
            for k, j in enumerate(new):  # M[:, j]: the torques of a unit acceleration of DOF j
                probe[2, j] += 1.0
                added[:, k] = inverse_dynamics(probe, *self._id_tree, gravity)[:n] - base  # type: ignore[call-arg]
                probe[2, j] = state[2, j]
            columns = np.concatenate([columns, added], axis=1)
            try:
                change = np.linalg.solve(columns[sat], bound[sat] - tau[sat])
            except np.linalg.LinAlgError:  # no fit: the torques as they came, clipped joint by joint as before it
                return tau
            out = tau + columns @ change
            out[sat] = bound[sat]
            more = (np.abs(out) > limit) & self.fit_dof
            more[sat] = False
            if not more.any():
                break
            bound[more] = np.copysign(limit[more], out[more])
            sat = np.concatenate([sat, np.flatnonzero(more)])
        return out

    def _mass_matrix(self, q_state: np.ndarray, n: int) -> np.ndarray:
        """The joint-space mass matrix (n, n), kg m^2, of the first ``n`` state columns at the angles ``q_state``
        (rad, state order: the 57 DOF then the passive joints), from the fixed-base copies (about 100 us)."""
        self._ensure_id_model()
        assert self._id is not None
        world, copies = self._id
        mass_state = np.zeros((len(q_state), len(q_state)))
        order, runs = self._id_order
        q_all = q_state[order].tolist()  # one conversion, each copy takes its run
        for (body_id, slots), (start, stop) in zip(copies, runs, strict=True):
            rows = world.client.calculateMassMatrix(body_id, q_all[start:stop])  # nested lists: read flat
            m = len(slots)
            mass_state[np.ix_(slots, slots)] = np.fromiter(chain.from_iterable(rows), float, m * m).reshape(m, m)
        return np.ascontiguousarray(mass_state[:n, :n])

    def stable_pd(self, theta: np.ndarray, theta_dot: np.ndarray, theta_t: np.ndarray, theta_dot_t: np.ndarray,
                  extra: np.ndarray, passive: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """Stable PD (Tan, Liu and Turk 2011), joint torques (n,) N m: the PD evaluated at the end of the step,
        ``tau = ks (theta_t - theta - dt theta_dot) + kd (theta_dot_t - theta_dot - dt theta_ddot) + extra``,
        the accelerations (rad/s^2) from ``(M + kd dt) theta_ddot = ks (theta_t - theta - dt theta_dot)
        + kd (theta_dot_t - theta_dot) + extra - C(q, qd) - g(q)``. ``extra``: torques added outside the PD
        (limits, gravity compensation). ``dt`` is the control period; ``passive``: the fulcrums' angles and
        velocities if already read.

        The same law as PyBullet's ``STABLE_PD_CONTROL``, computed here from the body's own mass matrix and
        inverse dynamics: PyBullet's needs a floating base, and on this body it is not deterministic (the same
        inputs give different torques, now and then NaN; see docs/physics.md)."""
        n = len(theta)
        passive = self.body.passive_state() if passive is None else passive
        bias = self._bias_torque(theta, theta_dot, passive)
        dt = self.control_dt
        position_error = theta_t - theta - dt * theta_dot
        rate_error = theta_dot_t - theta_dot
        implicit = self._mass_matrix(np.concatenate([theta, passive[0]]), n)
        implicit[np.diag_indices(n)] += self.kd * dt
        accel = np.linalg.solve(implicit, self.ks * position_error + self.kd * rate_error + extra - bias)
        return self.ks * position_error + self.kd * (rate_error - dt * accel) + extra

    def apply(self, theta: np.ndarray, theta_dot: np.ndarray, theta_t: np.ndarray, theta_dot_t: np.ndarray,
              passive_tau: np.ndarray, passive: tuple[np.ndarray, np.ndarray] | None = None) -> None:
        """Send this step's torques for the current mode (see the module docstring); ``passive``: the
        fulcrums' angles and velocities if already read."""
        body = self.body
        theta_t, extra = self.enforce_limits(theta, theta_t)
        last_rate = theta_dot_t if self._last_theta_dot_t is None else self._last_theta_dot_t
        self._last_theta_dot_t = theta_dot_t
        if self.mode in COMPUTED_TORQUE_MODES:
            tau = self.computed_torque(theta, theta_dot, theta_t, theta_dot_t, last_rate, passive) + extra
            assert self._ct_state is not None
            tau = self.fit_torque_limits(tau, self._ct_state)
        else:
            if self.params.gravity_compensation:
                extra = extra + self.gravity_torque(theta, passive)
            if self.mode == "joint_spd":
                tau = self.stable_pd(theta, theta_dot, theta_t, theta_dot_t, extra, passive)
            else:
                tau = self.ks * (theta_t - theta) + self.kd * (theta_dot_t - theta_dot) + extra
        if self.control_dt > self.world.dt:  # updates held over several steps (apply_between)
            if self.mode in COMPUTED_TORQUE_MODES:  # between updates: the same PD through the update's M(q)
                k_between = self._w_ct**2 * self.ct_ks
                d_between = 2 * self.params.damping_ratio * self._w_ct * self.ct_kd
                mass = self._ct_mass
            else:
                k_between, d_between, mass = self.ks, self.kd, None
            self._held = _HeldTorques(tau, theta.copy(), theta_dot.copy(), theta_dot_t.copy(), k_between,
                                      d_between, mass)
        self.last_tau = clip_torques(tau, body.torque_limit)
        self.torque_saturated += int(np.count_nonzero(np.abs(self.last_tau) >= body.torque_limit))
        body.send_torques(self.last_tau, passive_tau)

    @property
    def _w_ct(self) -> float:
        return 2 * math.pi * self.params.ct_frequency_hz

    def can_hold(self) -> bool:
        """Whether :meth:`apply_between` may stand in for a full update."""
        return self._held is not None

    def apply_between(self, theta: np.ndarray, theta_dot: np.ndarray, elapsed_s: float,
                      passive_tau: np.ndarray) -> None:
        """A physics step between two control updates: the last update's torques (PyBullet clears applied
        torques after every step), corrected by its PD for how the state moved since: ``tau = tau_0 +
        k (theta_0 + theta_dot_t elapsed - theta) + d (theta_dot_0 - theta_dot)``.

        For the explicit PD that is exactly the PD at the current state with the target moving on at its
        target velocity (gravity and limit torques held); for the computed-torque modes the same correction of
        the joint accelerations goes through the update's mass matrix ``M(q)``. ``elapsed_s``: seconds since
        the update.
        """
        held = self._held
        assert held is not None
        body = self.body
        tau = held_torque(held.tau, held.theta, held.theta_dot, held.theta_dot_t, held.k, held.d,
                          self._no_mass if held.mass is None else held.mass, elapsed_s, theta, theta_dot,
                          body.torque_limit)
        self.last_tau = tau
        self.torque_saturated += int(np.count_nonzero(np.abs(tau) >= body.torque_limit))
        body.send_torques(tau, passive_tau)


@dataclass(frozen=True)
class _HeldTorques:
    """The last full control update: unclipped torques (57,) N m, the state it saw (rad, rad/s), the
    target velocity (rad/s) and the PD used between updates."""

    tau: np.ndarray
    theta: np.ndarray
    theta_dot: np.ndarray
    theta_dot_t: np.ndarray
    k: np.ndarray
    d: np.ndarray
    mass: np.ndarray | None = None
    """Computed-torque modes: the joint-space mass matrix (57, 57) kg m^2 of the update; the correction is
    ``mass @ (k e + d e_dot)`` with k, d in 1/s^2 and 1/s. Explicit PD: None, k and d are the gains."""


def _conj(q: np.ndarray) -> np.ndarray:
    return np.array([-q[0], -q[1], -q[2], q[3]])


def leg_posture_rate(rate: np.ndarray, rest: np.ndarray, ref: np.ndarray, legs: np.ndarray) -> np.ndarray:
    """The null-space posture's rates (N,) rad/s with the legs' extra pull added: for each DOF of ``legs`` (indices)
    whose reference ``ref`` (N,) rad is more than :data:`LEG_POSTURE_BAND_RAD` from the posture ``rest`` (N,) rad,
    :data:`LEG_POSTURE_GAIN` times the excess toward it. ``rate`` itself when no leg is that far (the other DOF
    never change)."""
    d = rest[legs] - ref[legs]
    if np.abs(d).max() <= LEG_POSTURE_BAND_RAD:  # the usual case, checked first: 2 us a control update, not 5.5
        return rate
    excess = d - np.clip(d, -LEG_POSTURE_BAND_RAD, LEG_POSTURE_BAND_RAD)
    out = rate.copy()
    out[legs] += LEG_POSTURE_GAIN * excess
    return out
