"""Controllers: joint-space PD (explicit, PyBullet's stable PD, computed torque) and Cartesian DLS IK (Algorithm 2).

Modes: ``joint_pd`` (explicit PD below), ``joint_spd`` (PyBullet's stable PD,
experimental: it diverges on this body), ``joint_ct`` (the PD through inverse
dynamics, :meth:`Controller.computed_torque`), ``cartesian`` (Algorithm 2
feeding ``joint_ct``) and ``cartesian_pd`` (Algorithm 2 feeding ``joint_pd``).

Joint space (the paper's tracking): ``tau = ks (theta_t - theta) + kd (theta_dot_t - theta_dot)
+ tau_g``, with target velocities, gravity compensation ``tau_g`` (the torque
that holds every subtree against gravity), clipped to per-joint torque limits.
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
import pybullet as p

from services.physics.body import LIMBS, Body
from services.physics.character import JOINT_GROUP, JOINTS, joint_kind
from services.physics.limits import JointLimits
from services.physics.urdf import load_robot
from services.physics.world import World, WorldSettings

# ---------------------------------------------------------------------- quaternions (x y z w), vectorised


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of quaternions (K, 4) x y z w (or broadcastable (4,) / (K, 4))."""
    a = np.atleast_2d(a)
    b = np.atleast_2d(b)
    ax, ay, az, aw = a[:, 0], a[:, 1], a[:, 2], a[:, 3]
    bx, by, bz, bw = b[:, 0], b[:, 1], b[:, 2], b[:, 3]
    out = np.empty((max(len(a), len(b)), 4))
    out[:, 0] = aw * bx + ax * bw + ay * bz - az * by
    out[:, 1] = aw * by - ax * bz + ay * bw + az * bx
    out[:, 2] = aw * bz + ax * by - ay * bx + az * bw
    out[:, 3] = aw * bw - ax * bx - ay * by - az * bz
    return out


def quat_from_euler_xyz(e: np.ndarray) -> np.ndarray:
    """(K, 3) intrinsic x-y-z angles -> (K, 4) quaternions: q = qx(a) qy(b) qz(c)."""
    h = np.atleast_2d(e) / 2.0
    ca, sa = np.cos(h[:, 0]), np.sin(h[:, 0])
    cb, sb = np.cos(h[:, 1]), np.sin(h[:, 1])
    cc, sc = np.cos(h[:, 2]), np.sin(h[:, 2])
    out = np.empty((len(h), 4))
    out[:, 0] = sa * cb * cc + ca * sb * sc
    out[:, 1] = ca * sb * cc - sa * cb * sc
    out[:, 2] = ca * cb * sc + sa * sb * cc
    out[:, 3] = ca * cb * cc - sa * sb * sc
    return out


def quat_log(q: np.ndarray) -> np.ndarray:
    """(K, 4) unit quaternions -> (K, 3) rotation vectors (radians), shortest arc."""
    q = np.where(q[:, 3:4] < 0, -q, q)
    v = q[:, :3]
    s = np.sqrt(np.sum(v * v, axis=1))
    angle = 2.0 * np.arctan2(s, q[:, 3])
    scale = np.where(s > 1e-12, angle / np.maximum(s, 1e-12), 2.0)
    return v * scale[:, None]


def quat_exp(r: np.ndarray) -> np.ndarray:
    """(K, 3) rotation vectors -> (K, 4) unit quaternions."""
    angle = np.sqrt(np.sum(r * r, axis=1))
    half = angle / 2.0
    scale = np.where(angle > 1e-12, np.sin(half) / np.maximum(angle, 1e-12), 0.5)
    out = np.empty((len(r), 4))
    out[:, :3] = r * scale[:, None]
    out[:, 3] = np.cos(half)
    return out


def euler_xyz_from_quat(q: np.ndarray) -> np.ndarray:
    """(K, 4) -> (K, 3) intrinsic x-y-z angles (inverse of :func:`quat_from_euler_xyz`)."""
    x, y, z, w = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    r02 = 2 * (x * z + w * y)
    r12 = 2 * (y * z - w * x)
    r22 = 1 - 2 * (x * x + y * y)
    r01 = 2 * (x * y - w * z)
    r00 = 1 - 2 * (y * y + z * z)
    out = np.empty((len(q), 3))
    out[:, 0] = np.arctan2(-r12, r22)
    out[:, 1] = np.arcsin(np.clip(r02, -1.0, 1.0))
    out[:, 2] = np.arctan2(-r01, r00)
    return out


# ---------------------------------------------------------------------- settings

KD_CAP = 0.7

COMPUTED_TORQUE_MODES = ("joint_ct", "cartesian")
"""Modes whose PD goes through inverse dynamics; joint_pd and cartesian_pd use the explicit diagonal PD."""
"""Explicit damping stays below KD_CAP * I_free / dt (measured: 1.5 slowly destabilises the arms at 1 ms)."""

MASS_REFRESH_S = 0.03
"""Computed-torque modes with updates held over several steps: the joint-space mass matrix used between updates
is recomputed at least this often, seconds of simulation (it costs about 100 us, 20 times the inverse dynamics,
and only scales the small correction between updates; the update itself is exact inverse dynamics)."""

TRUNK_IK_WEIGHT = 0.3
"""Inverse DLS weight of the lumbar and thoracic DOF (0: they keep the posture; 1: as free as the arms)."""


@dataclass
class ControlParams:
    """Live-tunable controller parameters.

    ``frequency_hz``/``damping_ratio``: PD natural frequency and damping;
    ``ik_damping``: DLS lambda (metres); ``posture_gain``: null-space pull
    toward the rest posture (1/s); ``task_gain`` / ``task_gain_pd``: Cartesian
    error feedback (1/s) with the computed-torque / the explicit PD;
    ``gravity_compensation``: add tau_g; ``max_joint_speed``: the IK's joint velocity reference is scaled
    down to at most this (rad/s), a guard near singular (stretched) arm configurations.
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
        # joint-space inertia at the rest posture (a floating base: 6 base DOF first, then every joint)
        body.set_state(rest)
        q_all = [c.getJointState(body.id, j)[0] for j in range(c.getNumJoints(body.id))
                 if c.getJointInfo(body.id, j)[2] == p.JOINT_REVOLUTE]
        movable = [j for j in range(c.getNumJoints(body.id)) if c.getJointInfo(body.id, j)[2] == p.JOINT_REVOLUTE]
        base: list[float] = []
        if body.floating_base:
            base_pos, base_quat = c.getBasePositionAndOrientation(body.id)
            base = [*base_pos, *base_quat]
        mass = np.asarray(c.calculateMassMatrix(body.id, [*base, *q_all]))
        offset = mass.shape[0] - len(movable)
        col = {j: offset + k for k, j in enumerate(movable)}
        # effective inertia of each DOF with every other joint free: 1 / (M^-1)_jj. The diagonal of M itself
        # (others locked) overestimates it for short links between co-linear DOF (clavicle-shoulder, neck-head),
        # whose explicit PD then goes unstable at a 1 ms step
        inv = np.linalg.inv(mass)
        self.inertia_locked = np.array([mass[col[j], col[j]] for j in body.dof_list])
        self.inertia = np.array([max(1.0 / inv[col[j], col[j]], 1e-4) for j in body.dof_list])
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
        self._limit_tiles: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = {}
        if self.q_joints:
            self.q_mean_inv = np.array([_conj(limits.quaternion[j].mean) for j in self.q_joints])
            self.q_mean = np.array([limits.quaternion[j].mean for j in self.q_joints])
            self.q_axes = np.array([limits.quaternion[j].axes for j in self.q_joints])
            self.q_extents = np.array([limits.quaternion[j].extents for j in self.q_joints])
        # gravity compensation: subtree masses per DOF
        self._links = list(range(c.getNumJoints(body.id)))
        self._link_mass = np.array([c.getDynamicsInfo(body.id, j)[0] for j in self._links])
        parent = {j: c.getJointInfo(body.id, j)[16] for j in self._links}
        self._desc = np.zeros((n, len(self._links)))
        dof_pos = {j: k for k, j in enumerate(body.dof_list)}
        for link in self._links:
            a = link
            while a >= 0:
                if a in dof_pos:
                    self._desc[dof_pos[a], link] = 1.0
                a = parent[a]
        self._g = np.array([0.0, 0.0, -world.settings.gravity])
        self.limit_violations = 0
        self.last_tau = np.zeros(n)
        self.theta_ref: np.ndarray | None = None
        self._id: tuple[World, int, np.ndarray, np.ndarray, int] | None = None
        self._last_theta_dot_t: np.ndarray | None = None
        self.touching: set[str] = set()
        """Limbs whose stick touches an instrument at the last step (set by the scene before apply)."""
        self.posture_rate: np.ndarray | None = None
        """Rates (57,) rad/s of a moving null-space posture (``rest``), fed forward by the IK; None: still."""

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
        self.kd = np.minimum(np.maximum(2 * zeta * w * self.inertia, kd_slow), kd_cap) * self.scale_kd

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
        q = quat_from_euler_xyz(e)
        tiles = self._limit_tiles.get(repeat)
        if tiles is None:  # the limits stacked ``repeat`` times, made once
            tiles = self._limit_tiles[repeat] = (
                np.tile(self.q_mean_inv, (repeat, 1)), np.tile(self.q_mean, (repeat, 1)),
                np.tile(self.q_axes, (repeat, 1, 1)), np.tile(self.q_extents, (repeat, 1)))
        mean_inv, mean, axes, extents = tiles
        v = quat_log(quat_mul(mean_inv, q))
        coords = np.einsum("kij,ki->kj", axes, v)
        r = np.sqrt(np.sum((coords / extents) ** 2, axis=1))
        outside = r > 1.0
        if not np.any(outside):
            return e, outside
        scale = np.where(outside, 1.0 / np.maximum(r, 1e-12), 1.0)
        qp = quat_mul(mean, quat_exp(v * scale[:, None]))
        return euler_xyz_from_quat(qp), outside

    def limit_torque(self, theta: np.ndarray) -> np.ndarray:
        """Restoring torque (57,) for joints outside their quaternion ellipsoid."""
        return self.enforce_limits(theta, np.clip(theta, self.body.lower, self.body.upper))[1]

    def enforce_limits(self, theta: np.ndarray, theta_t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(targets projected into the quaternion ellipsoids (57,), restoring torque for the state (57,)).

        One vectorised projection for both (the state's and the targets' limited joints, stacked).
        """
        tau = np.zeros_like(theta)
        if not self.q_joints:
            return theta_t, tau
        k = len(self.q_joints)
        e = np.concatenate([theta[self.q_index], theta_t[self.q_index]])
        proj, outside = self._project(e, repeat=2)
        out = theta_t
        if np.any(outside[k:]):
            out = theta_t.copy()
            out[self.q_index[outside[k:]]] = proj[k:][outside[k:]]
            out = np.clip(out, self.body.lower, self.body.upper)
        if np.any(outside[:k]):
            self.limit_violations += int(outside[:k].sum())
            idx = self.q_index[outside[:k]]
            tau[idx] = self.params.limit_stiffness_scale * self.ks[idx] * (proj[:k][outside[:k]] - e[:k][outside[:k]])
        return out, tau

    # ------------------------------------------------------------------ gravity

    def gravity_torque(self) -> np.ndarray:
        """Joint torques (57,) that hold every subtree against gravity at the current pose (from Body.update)."""
        b = self.body
        weighted = self._desc @ (self._link_mass[:, None] * b.link_com)  # (57, 3): sum of m_i c_i over subtree
        sub_mass = self._desc @ self._link_mass
        r = weighted - sub_mass[:, None] * b.dof_pos
        g = self._g
        moment = np.stack([r[:, 1] * g[2] - r[:, 2] * g[1], r[:, 2] * g[0] - r[:, 0] * g[2],
                           r[:, 0] * g[1] - r[:, 1] * g[0]], axis=1)
        return -np.einsum("ij,ij->i", b.dof_axes, moment)

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
        eff, jac = self.body.kinematics()
        rows = [LIMBS.index(limb) for limb in LIMBS if limb in targets]
        if self.theta_ref is None:
            self.theta_ref = theta.copy()
        if not rows:
            self.theta_ref = self.rest.copy()
            return self.rest.copy(), np.zeros_like(theta)
        ref = self.theta_ref
        j = jac[rows].reshape(3 * len(rows), -1)
        # a touching limb whose target is below it would only push into the surface: hold its error
        pressing = {LIMBS[r] for r in rows if LIMBS[r] in touching and targets[LIMBS[r]][0][2] < eff[r][2]}
        err = np.concatenate([(targets[LIMBS[r]][0] - eff[r]) * (LIMBS[r] not in pressing) for r in rows])
        vel = np.concatenate([targets[LIMBS[r]][1] for r in rows])
        gain = self.params.task_gain if self.mode in COMPUTED_TORQUE_MODES else self.params.task_gain_pd
        xdot = vel + gain * err
        jw = j * self.ik_weight_inv[None, :]
        a = jw @ j.T
        a.flat[:: a.shape[0] + 1] += self.params.ik_damping**2
        jpinv = np.linalg.solve(a, jw).T  # W^-1 J^T (J W^-1 J^T + lambda^2 I)^-1 (a is symmetric)
        active = self.body.chain_mask[rows].any(axis=0)
        pull = self.params.posture_gain * (self.rest - ref)
        if self.posture_rate is not None:
            pull += self.posture_rate
        posture = np.where(active, pull, 0.0)
        null_term = posture - jpinv @ (j @ posture)
        qdot = jpinv @ xdot + null_term
        fastest = float(np.max(np.abs(qdot)))
        if fastest > self.params.max_joint_speed:  # near a singularity (arm stretched): slow down, do not whip
            qdot *= self.params.max_joint_speed / fastest
        new_ref = np.where(active, ref + qdot * self.control_dt, self.rest)
        # keep the reference within reach of the state (no wind-up) and inside the Euler boxes (apply()
        # projects the targets into the quaternion limits)
        lead = np.full(len(theta), self.params.max_lead_rad)
        for limb in pressing:  # a stick on a head: let it bounce, do not push it through
            lead[self.body.chain_mask[LIMBS.index(limb)]] = self.params.contact_lead_rad
        new_ref = theta + np.clip(new_ref - theta, -lead, lead)
        new_ref = np.clip(new_ref, self.body.lower, self.body.upper)
        self.theta_ref = new_ref
        return new_ref, np.where(active, qdot, 0.0)

    # ------------------------------------------------------------------ apply

    def close(self) -> None:
        if self._id is not None:
            self._id[0].close()
            self._id = None

    def _ensure_id_model(self) -> None:
        """A fixed-base copy of the body in its own client, for inverse dynamics (RNEA, ~20 us a call)."""
        if self._id is not None:
            return
        world = World(WorldSettings(timestep_s=self.world.dt))
        world.client.setGravity(0.0, 0.0, -self.world.settings.gravity)
        body_id = load_robot(world.client, self.body.model.robot, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0),
                             fixed_base=True, flags=p.URDF_USE_INERTIA_FROM_FILE)
        c = world.client
        revolute = [j for j in range(c.getNumJoints(body_id)) if c.getJointInfo(body_id, j)[2] == p.JOINT_REVOLUTE]
        pos = {j: k for k, j in enumerate(revolute)}
        self._id = (world, body_id, np.array([pos[j] for j in self.body.dof_list]),
                    np.array([pos[j] for j in self.body.passive]), len(revolute))
        dof_pos = self._id[2]
        self._dof_block = (dof_pos[:, None] * len(revolute) + dof_pos[None, :]).reshape(-1)
        """Flat indices of the DOF x DOF block of the copy's mass matrix (which also has the fulcrums)."""

    def computed_torque(self, theta: np.ndarray, theta_dot: np.ndarray, theta_t: np.ndarray,
                        theta_dot_t: np.ndarray, theta_ddot_ff: np.ndarray,
                        passive: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """tau = M(q) (qdd_ff + w^2 (q_t - q) + 2 zeta w (qd_t - qd)) + C(q, qd) + g(q): a PD whose gains are
        scaled by the body's own inertia (inverse dynamics on a fixed-base copy; the seat does not move).

        ``passive``: the fulcrum angles and velocities (rad, rad/s) if already read. With updates held over
        several steps, ``M(q)`` for the correction between updates is refreshed every ``MASS_REFRESH_S``
        (the posture changes little in that time)."""
        self._ensure_id_model()
        assert self._id is not None
        world, body_id, dof_pos, passive_pos, n = self._id
        w = 2 * math.pi * self.params.ct_frequency_hz
        zeta = self.params.damping_ratio
        soft = np.ones(len(theta))
        for limb in self.touching:  # a relaxed grip while the stick is on a head
            soft[self.body.chain_mask[LIMBS.index(limb)]] = self.params.contact_softening
        qdd = theta_ddot_ff * soft + w * w * soft**2 * (theta_t - theta) * self.scale_ks \
            + 2 * zeta * w * soft * (theta_dot_t - theta_dot) * self.scale_kd
        q_all = np.zeros(n)
        qd_all = np.zeros(n)
        qdd_all = np.zeros(n)
        q_all[dof_pos], qd_all[dof_pos], qdd_all[dof_pos] = theta, theta_dot, qdd
        pq, pqd = self.body.passive_state() if passive is None else passive
        q_all[passive_pos], qd_all[passive_pos] = pq, pqd
        q_list = q_all.tolist()
        tau = world.client.calculateInverseDynamics(body_id, q_list, qd_all.tolist(), qdd_all.tolist())
        if self.control_dt > self.world.dt:  # held between updates: keep M(q) for the PD's correction
            self._mass_age += self.control_dt
            if self._ct_mass is None or self._mass_age >= MASS_REFRESH_S - 1e-9:
                rows = world.client.calculateMassMatrix(body_id, q_list)  # nested lists: read flat, not np.array
                mass = np.fromiter(chain.from_iterable(rows), float, n * n)
                self._ct_mass = mass.take(self._dof_block).reshape(len(dof_pos), len(dof_pos))
                self._mass_age = 0.0
        return np.asarray(tau)[dof_pos]

    def apply(self, theta: np.ndarray, theta_dot: np.ndarray, theta_t: np.ndarray, theta_dot_t: np.ndarray,
              passive_tau: np.ndarray, passive: tuple[np.ndarray, np.ndarray] | None = None) -> None:
        """Send this step's torques for the current mode (see the module docstring); ``passive``: the
        fulcrums' angles and velocities if already read."""
        c = self.world.client
        body = self.body
        theta_t, extra = self.enforce_limits(theta, np.clip(theta_t, body.lower, body.upper))
        if self._last_theta_dot_t is None:
            self._last_theta_dot_t = theta_dot_t.copy()
        qdd_ff = np.clip((theta_dot_t - self._last_theta_dot_t) / self.control_dt, -self.params.max_ff_accel,
                         self.params.max_ff_accel)
        self._last_theta_dot_t = theta_dot_t.copy()
        if self.mode == "joint_spd":
            # PyBullet's stable PD with the pinned floating base; gravity and limit torques are
            # not expressible there, so they go in as the PD's target shift tau / ks
            if self.params.gravity_compensation:
                extra = extra + self.gravity_torque()
            shift = extra / np.maximum(self.ks, 1e-9)
            target = theta_t + shift
            c.setJointMotorControlMultiDofArray(
                body.id, body.dof_list, p.STABLE_PD_CONTROL,
                targetPositions=[[float(v)] for v in target],
                targetVelocities=[[float(v)] for v in theta_dot_t],
                positionGains=[float(v) for v in self.ks],
                velocityGains=[float(v) for v in self.kd],
                forces=[[float(v)] for v in body.torque_limit],
            )
            self.last_tau = np.zeros_like(theta)
        else:
            if self.mode in COMPUTED_TORQUE_MODES:
                tau = self.computed_torque(theta, theta_dot, theta_t, theta_dot_t, qdd_ff, passive) + extra
                # between control updates: the same PD through the mass matrix of the update
                k_between = self._w_ct**2 * self.scale_ks
                d_between = 2 * self.params.damping_ratio * self._w_ct * self.scale_kd
                mass = self._ct_mass
            else:
                if self.params.gravity_compensation:
                    extra = extra + self.gravity_torque()
                tau = self.ks * (theta_t - theta) + self.kd * (theta_dot_t - theta_dot) + extra
                k_between, d_between, mass = self.ks, self.kd, None
            self._held = _HeldTorques(tau, theta.copy(), theta_dot.copy(), theta_dot_t.copy(), k_between, d_between,
                                      mass)
            tau = np.clip(tau, -body.torque_limit, body.torque_limit)
            self.last_tau = tau
            c.setJointMotorControlArray(body.id, body.state_joints, p.TORQUE_CONTROL,
                                        forces=tau.tolist() + passive_tau.tolist())
            return
        c.setJointMotorControlArray(body.id, body.passive, p.TORQUE_CONTROL, forces=passive_tau.tolist())

    @property
    def _w_ct(self) -> float:
        return 2 * math.pi * self.params.ct_frequency_hz

    def can_hold(self) -> bool:
        """Whether :meth:`apply_between` may stand in for a full update (PyBullet's stable PD may not)."""
        return self._held is not None and self.mode != "joint_spd"

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
        correction = held.k * (held.theta + held.theta_dot_t * elapsed_s - theta) \
            + held.d * (held.theta_dot - theta_dot)
        tau = held.tau + (correction if held.mass is None else held.mass @ correction)
        tau = np.clip(tau, -body.torque_limit, body.torque_limit)
        self.last_tau = tau
        self.world.client.setJointMotorControlArray(body.id, body.state_joints, p.TORQUE_CONTROL,
                                                    forces=tau.tolist() + passive_tau.tolist())


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
