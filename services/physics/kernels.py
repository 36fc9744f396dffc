"""Compiled numeric kernels of the body and its controller (numba): joint frames, Jacobians, the damped
least-squares reference of Algorithm 2, quaternion joint limits, the held-torque correction, Hermite samples.

The controller's arrays are small (57 DOF, up to 12 task rows), so NumPy's per-call overhead (about 1-40 us
a call: ``np.linalg.solve`` of a 12 x 12 system costs 38 us) was most of a control update; these loops do
the same arithmetic in a few microseconds. Pure functions of arrays, no state; compiled on first use and
cached on disk next to this file (``cache=True``), so only the first process of a fresh install pays the
compilation (a few seconds).

Conventions: quaternions (x, y, z, w); intrinsic x-y-z Euler angles (``Rx(a) Ry(b) Rz(c)``); radians,
metres, seconds, N m.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

# ---------------------------------------------------------------------- quaternions and Euler angles


@njit(cache=True)
def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of two quaternions (4,)."""
    out = np.empty(4)
    out[0] = a[3] * b[0] + a[0] * b[3] + a[1] * b[2] - a[2] * b[1]
    out[1] = a[3] * b[1] - a[0] * b[2] + a[1] * b[3] + a[2] * b[0]
    out[2] = a[3] * b[2] + a[0] * b[1] - a[1] * b[0] + a[2] * b[3]
    out[3] = a[3] * b[3] - a[0] * b[0] - a[1] * b[1] - a[2] * b[2]
    return out


@njit(cache=True)
def _quat_from_euler(a: float, b: float, c: float) -> np.ndarray:
    """Quaternion of ``Rx(a) Ry(b) Rz(c)``."""
    ca, sa = math.cos(a / 2), math.sin(a / 2)
    cb, sb = math.cos(b / 2), math.sin(b / 2)
    cc, sc = math.cos(c / 2), math.sin(c / 2)
    out = np.empty(4)
    out[0] = sa * cb * cc + ca * sb * sc
    out[1] = ca * sb * cc - sa * cb * sc
    out[2] = ca * cb * sc + sa * sb * cc
    out[3] = ca * cb * cc - sa * sb * sc
    return out


@njit(cache=True)
def _euler_from_quat(q: np.ndarray) -> np.ndarray:
    """Intrinsic x-y-z angles (3,) of a unit quaternion (inverse of :func:`_quat_from_euler`)."""
    x, y, z, w = q[0], q[1], q[2], q[3]
    r02 = 2 * (x * z + w * y)
    r12 = 2 * (y * z - w * x)
    r22 = 1 - 2 * (x * x + y * y)
    r01 = 2 * (x * y - w * z)
    r00 = 1 - 2 * (y * y + z * z)
    out = np.empty(3)
    out[0] = math.atan2(-r12, r22)
    out[1] = math.asin(min(max(r02, -1.0), 1.0))
    out[2] = math.atan2(-r01, r00)
    return out


@njit(cache=True)
def _quat_log(q: np.ndarray) -> np.ndarray:
    """Rotation vector (3,) radians of a unit quaternion, shortest arc."""
    sign = -1.0 if q[3] < 0 else 1.0
    vx, vy, vz, w = sign * q[0], sign * q[1], sign * q[2], sign * q[3]
    s = math.sqrt(vx * vx + vy * vy + vz * vz)
    angle = 2.0 * math.atan2(s, w)
    scale = angle / s if s > 1e-12 else 2.0
    out = np.empty(3)
    out[0], out[1], out[2] = vx * scale, vy * scale, vz * scale
    return out


@njit(cache=True)
def _quat_exp(r: np.ndarray) -> np.ndarray:
    """Unit quaternion of a rotation vector (3,) radians."""
    angle = math.sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2])
    scale = math.sin(angle / 2) / angle if angle > 1e-12 else 0.5
    out = np.empty(4)
    out[0], out[1], out[2] = r[0] * scale, r[1] * scale, r[2] * scale
    out[3] = math.cos(angle / 2)
    return out


@njit(cache=True)
def project_into_ellipsoids(e: np.ndarray, mean_inv: np.ndarray, mean: np.ndarray, axes: np.ndarray,
                            extents: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Project Euler triples into their joints' quaternion limit ellipsoids (Algorithm 1's limits).

    ``e`` (R K, 3): the triples of K limited joints, R times over (the state's and the targets' stacked);
    ``mean_inv``, ``mean`` (K, 4): each joint's mean orientation and its inverse; ``axes`` (K, 3, 3): principal
    axes as columns; ``extents`` (K, 3): radians along them. Returns the projected triples (R K, 3) (a triple
    inside its ellipsoid is returned as is) and which were outside (R K,).
    """
    k = mean.shape[0]
    proj = e.copy()
    outside = np.zeros(e.shape[0], dtype=np.bool_)
    coords = np.empty(3)
    for row in range(e.shape[0]):
        j = row % k
        v = _quat_log(_quat_mul(mean_inv[j], _quat_from_euler(e[row, 0], e[row, 1], e[row, 2])))
        r2 = 0.0
        for c in range(3):
            coords[c] = axes[j, 0, c] * v[0] + axes[j, 1, c] * v[1] + axes[j, 2, c] * v[2]
            r2 += (coords[c] / extents[j, c]) ** 2
        r = math.sqrt(r2)
        if r > 1.0:
            outside[row] = True
            proj[row] = _euler_from_quat(_quat_mul(mean[j], _quat_exp(v / r)))
    return proj, outside


@njit(cache=True)
def enforce_limits(theta: np.ndarray, theta_t: np.ndarray, q_index: np.ndarray, mean_inv: np.ndarray,
                   mean: np.ndarray, axes: np.ndarray, extents: np.ndarray, ks: np.ndarray, stiffness_scale: float,
                   lower: np.ndarray, upper: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """Joint limits for one control update: the targets ``theta_t`` (N,) clipped to the Euler boxes
    (``lower``, ``upper``) and projected into the quaternion ellipsoids of the K joints whose DOF are
    ``q_index`` (K, 3), and a restoring torque (N,) N m, ``stiffness_scale ks`` times the distance to the
    projection, on the DOF of joints whose *state* ``theta`` (N,) is outside its ellipsoid. Returns the targets,
    the torque and how many joints were outside."""
    k = q_index.shape[0]
    e = np.empty((2 * k, 3))
    out = np.empty(theta_t.shape[0])
    for i in range(theta_t.shape[0]):
        out[i] = min(max(theta_t[i], lower[i]), upper[i])
    for j in range(k):
        for c in range(3):
            e[j, c] = theta[q_index[j, c]]
            e[k + j, c] = out[q_index[j, c]]
    proj, outside = project_into_ellipsoids(e, mean_inv, mean, axes, extents)
    tau = np.zeros(theta.shape[0])
    violations = 0
    for j in range(k):
        if outside[k + j]:
            for c in range(3):
                i = q_index[j, c]
                out[i] = min(max(proj[k + j, c], lower[i]), upper[i])
        if outside[j]:
            violations += 1
            for c in range(3):
                i = q_index[j, c]
                tau[i] = stiffness_scale * ks[i] * (proj[j, c] - e[j, c])
    return out, tau, violations


# ---------------------------------------------------------------------- kinematics


@njit(cache=True)
def forward_kinematics(q: np.ndarray, parent: np.ndarray, offset: np.ndarray, base_pos: np.ndarray,
                       base_rot: np.ndarray, effector_joint: np.ndarray,
                       effector_offset: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Forward kinematics of J three-DOF joints, each ``Rx(a) Ry(b) Rz(c)`` about its child's origin.

    ``q`` (3 J,) radians, joint-major (x, y, z of each joint); ``parent`` (J,): the joint whose child link
    carries this joint (-1: a base), parents before children; ``offset`` (J, 3): the joint's origin in its
    parent's child frame (a root joint's: in its base frame), metres; ``base_pos`` (J, 3) and ``base_rot``
    (J, 3, 3): a root joint's base frame in the world (other rows unused); ``effector_joint`` (E,) and
    ``effector_offset`` (E, 3): points fixed in a joint's child frame. Returns the DOF origins (3 J, 3) and world
    axes (3 J, 3), the joints' child origins (J, 3) and the effectors (E, 3), metres.

    The x axis is the parent's x, the y axis that of the frame turned by ``Rx(a)``, the z axis the child's.
    """
    n_joints = parent.shape[0]
    rot = np.empty((n_joints, 3, 3))
    pos = np.empty((n_joints, 3))
    dof_pos = np.empty((3 * n_joints, 3))
    dof_axes = np.empty((3 * n_joints, 3))
    r1 = np.empty((3, 3))
    r2 = np.empty((3, 3))
    for j in range(n_joints):
        rp = base_rot[j] if parent[j] < 0 else rot[parent[j]]
        pp = base_pos[j] if parent[j] < 0 else pos[parent[j]]
        for i in range(3):
            pos[j, i] = pp[i] + rp[i, 0] * offset[j, 0] + rp[i, 1] * offset[j, 1] + rp[i, 2] * offset[j, 2]
        ca, sa = math.cos(q[3 * j]), math.sin(q[3 * j])
        cb, sb = math.cos(q[3 * j + 1]), math.sin(q[3 * j + 1])
        cc, sc = math.cos(q[3 * j + 2]), math.sin(q[3 * j + 2])
        for i in range(3):  # r1 = rp Rx(a), r2 = r1 Ry(b), child = r2 Rz(c)
            r1[i, 0] = rp[i, 0]
            r1[i, 1] = rp[i, 1] * ca + rp[i, 2] * sa
            r1[i, 2] = -rp[i, 1] * sa + rp[i, 2] * ca
            r2[i, 0] = r1[i, 0] * cb - r1[i, 2] * sb
            r2[i, 1] = r1[i, 1]
            r2[i, 2] = r1[i, 0] * sb + r1[i, 2] * cb
            rot[j, i, 0] = r2[i, 0] * cc + r2[i, 1] * sc
            rot[j, i, 1] = -r2[i, 0] * sc + r2[i, 1] * cc
            rot[j, i, 2] = r2[i, 2]
            dof_axes[3 * j, i] = rp[i, 0]
            dof_axes[3 * j + 1, i] = r1[i, 1]
            dof_axes[3 * j + 2, i] = r2[i, 2]
        for k in range(3):
            dof_pos[3 * j + k] = pos[j]
    eff = np.empty((effector_joint.shape[0], 3))
    for e in range(effector_joint.shape[0]):
        j = effector_joint[e]
        for i in range(3):
            eff[e, i] = pos[j, i] + rot[j, i, 0] * effector_offset[e, 0] + rot[j, i, 1] * effector_offset[e, 1] \
                + rot[j, i, 2] * effector_offset[e, 2]
    return dof_pos, dof_axes, pos, eff


@njit(cache=True)
def jacobian(points: np.ndarray, dof_pos: np.ndarray, dof_axes: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Geometric Jacobians (L, 3, N) of L points (L, 3) fixed to links, for N revolute DOF: column k is
    ``axis_k x (p - o_k)`` where ``mask[l, k]`` (DOF k moves the point's link), else 0."""
    n_points, n = points.shape[0], dof_pos.shape[0]
    jac = np.zeros((n_points, 3, n))
    for i in range(n_points):
        for k in range(n):
            if mask[i, k]:
                d0 = points[i, 0] - dof_pos[k, 0]
                d1 = points[i, 1] - dof_pos[k, 1]
                d2 = points[i, 2] - dof_pos[k, 2]
                a0, a1, a2 = dof_axes[k, 0], dof_axes[k, 1], dof_axes[k, 2]
                jac[i, 0, k] = a1 * d2 - a2 * d1
                jac[i, 1, k] = a2 * d0 - a0 * d2
                jac[i, 2, k] = a0 * d1 - a1 * d0
    return jac


@njit(cache=True)
def _cholesky_solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """X = A^-1 B for a symmetric positive definite A (m, m) and B (m, n)."""
    m = a.shape[0]
    low = np.zeros((m, m))
    for i in range(m):
        for j in range(i + 1):
            s = a[i, j]
            for k in range(j):
                s -= low[i, k] * low[j, k]
            low[i, j] = math.sqrt(s) if i == j else s / low[j, j]
    x = b.copy()
    for col in range(b.shape[1]):
        for i in range(m):  # L y = b
            s = x[i, col]
            for k in range(i):
                s -= low[i, k] * x[k, col]
            x[i, col] = s / low[i, i]
        for i in range(m - 1, -1, -1):  # L^T x = y
            s = x[i, col]
            for k in range(i + 1, m):
                s -= low[k, i] * x[k, col]
            x[i, col] = s / low[i, i]
    return x


@njit(cache=True)
def dls_reference(theta: np.ndarray, ref: np.ndarray, rest: np.ndarray, posture_rate: np.ndarray,
                  eff: np.ndarray, dof_pos: np.ndarray, dof_axes: np.ndarray, chain_mask: np.ndarray,
                  rows: np.ndarray, target_pos: np.ndarray, target_vel: np.ndarray, pressing: np.ndarray,
                  weight_inv: np.ndarray, damping: float, gain: float, posture_gain: float, dt: float,
                  max_joint_speed: float, max_lead: float, contact_lead: float, lower: np.ndarray,
                  upper: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One step of Algorithm 2's joint reference (see :meth:`Controller.ik_targets` for the law).

    ``theta`` (N,) the state, ``ref`` (N,) the reference, ``rest`` (N,) the null-space posture and
    ``posture_rate`` (N,) its rate (rad, rad/s); ``eff`` (4, 3) the effectors (LIMBS order) and
    ``chain_mask`` (4, N) the DOF that move each; ``rows`` (m,) the limbs with targets, ``target_pos`` and
    ``target_vel`` (m, 3) their targets (m, m/s), ``pressing`` (m,) the limbs whose error is held (touching,
    target below); ``weight_inv`` (N,) the DLS's inverse weights; ``damping`` lambda (m); ``gain`` the task
    feedback (1/s); ``posture_gain`` (1/s); ``dt`` the control period (s); ``max_joint_speed`` (rad/s);
    ``max_lead`` and ``contact_lead`` (rad) how far the reference may lead the state. Returns the new
    reference (N,) and its rate (N,), zero for the DOF no limb with a target moves.
    """
    n = theta.shape[0]
    m = rows.shape[0]
    points = np.empty((m, 3))
    mask = np.zeros((m, n), dtype=np.bool_)
    for i in range(m):
        points[i] = eff[rows[i]]
        mask[i] = chain_mask[rows[i]]
    jac3 = jacobian(points, dof_pos, dof_axes, mask)
    j = jac3.reshape(3 * m, n)
    xdot = np.empty(3 * m)
    for i in range(m):
        for c in range(3):
            err = 0.0 if pressing[i] else target_pos[i, c] - points[i, c]
            xdot[3 * i + c] = target_vel[i, c] + gain * err
    jw = j * weight_inv.reshape(1, n)
    a = jw @ j.T
    for i in range(3 * m):
        a[i, i] += damping * damping
    active = np.zeros(n, dtype=np.bool_)
    for i in range(m):
        active |= mask[i]
    posture = np.where(active, posture_gain * (rest - ref) + posture_rate, 0.0)
    # with J+ = W^-1 J^T A^-1 (A = J W^-1 J^T + lambda^2 I, symmetric), J+ xdot + (I - J+ J) posture is
    # W^-1 J^T A^-1 (xdot - J posture) + posture: one solve of the task-sized system
    y = _cholesky_solve(a, (xdot - j @ posture).reshape(3 * m, 1))
    qdot = (jw.T @ y).reshape(n) + posture
    fastest = np.max(np.abs(qdot))
    if fastest > max_joint_speed:  # near a singularity (arm stretched): slow down, do not whip
        qdot *= max_joint_speed / fastest
    lead = np.full(n, max_lead)
    for i in range(m):
        if pressing[i]:
            for k in range(n):
                if mask[i, k]:
                    lead[k] = contact_lead
    new_ref = np.empty(n)
    for k in range(n):
        r = ref[k] + qdot[k] * dt if active[k] else rest[k]
        r = theta[k] + min(max(r - theta[k], -lead[k]), lead[k])
        new_ref[k] = min(max(r, lower[k]), upper[k])
        if not active[k]:
            qdot[k] = 0.0
    return new_ref, qdot


# ---------------------------------------------------------------------- torques and targets


@njit(cache=True)
def clip_torques(tau: np.ndarray, limit: np.ndarray) -> np.ndarray:
    """``tau`` (N,) N m within ``[-limit, limit]`` (N,) as a new array (``np.clip``'s result, NaN kept)."""
    out = tau.copy()
    for i in range(tau.shape[0]):
        if out[i] > limit[i]:
            out[i] = limit[i]
        elif out[i] < -limit[i]:
            out[i] = -limit[i]
    return out


@njit(cache=True)
def held_torque(tau0: np.ndarray, theta0: np.ndarray, theta_dot0: np.ndarray, theta_dot_t: np.ndarray,
                k: np.ndarray, d: np.ndarray, mass: np.ndarray, elapsed_s: float, theta: np.ndarray,
                theta_dot: np.ndarray, limit: np.ndarray) -> np.ndarray:
    """A held control update's torques (N,) N m corrected for how the state moved since, clipped to ``limit``:
    ``tau0 + M (k (theta0 + theta_dot_t elapsed - theta) + d (theta_dot0 - theta_dot))`` (``M`` the identity
    when ``mass`` is empty (0, 0): the explicit PD, whose k and d are its gains)."""
    n = tau0.shape[0]
    corr = k * (theta0 + theta_dot_t * elapsed_s - theta) + d * (theta_dot0 - theta_dot)
    if mass.shape[0] == n:
        corr = mass @ corr
    out = np.empty(n)
    for i in range(n):
        out[i] = min(max(tau0[i] + corr[i], -limit[i]), limit[i])
    return out


@njit(cache=True)
def computed_torque_state(theta: np.ndarray, theta_dot: np.ndarray, theta_t: np.ndarray, theta_dot_t: np.ndarray,
                          last_theta_dot_t: np.ndarray, dt: float, max_ff: float, soft: np.ndarray,
                          scale_ks: np.ndarray, scale_kd: np.ndarray, w: float, zeta: float, passive_q: np.ndarray,
                          passive_qd: np.ndarray) -> np.ndarray:
    """The inverse dynamics' input (3, N + P): joint angles (rad), rates (rad/s) and the accelerations (rad/s^2)
    ``qdd_ff s + w^2 s^2 ks (theta_t - theta) + 2 zeta w s kd (theta_dot_t - theta_dot)`` of the computed-torque
    PD (``qdd_ff`` the target rate's change from ``last_theta_dot_t`` over ``dt`` seconds, within ``max_ff``;
    ``s`` the grip softening per DOF; ``ks``, ``kd`` the gain scales), then the P passive joints' angles and
    rates (accelerations 0: the fingers are not driven)."""
    n, extra = theta.shape[0], passive_q.shape[0]
    state = np.zeros((3, n + extra))
    for i in range(n):
        s = soft[i]
        ff = min(max((theta_dot_t[i] - last_theta_dot_t[i]) / dt, -max_ff), max_ff)
        state[0, i] = theta[i]
        state[1, i] = theta_dot[i]
        state[2, i] = ff * s + w * w * s * s * (theta_t[i] - theta[i]) * scale_ks[i] \
            + 2 * zeta * w * s * (theta_dot_t[i] - theta_dot[i]) * scale_kd[i]
    for i in range(extra):
        state[0, n + i] = passive_q[i]
        state[1, n + i] = passive_qd[i]
    return state


@njit(cache=True)
def inverse_dynamics(state: np.ndarray, parent: np.ndarray, origin_pos: np.ndarray, origin_rot: np.ndarray,
                     axis: np.ndarray, slot: np.ndarray, mass: np.ndarray, com: np.ndarray, inertia: np.ndarray,
                     gravity: float) -> np.ndarray:
    """Joint torques (N,) N m that give the accelerations ``state[2]`` at the angles ``state[0]`` (rad) and rates
    ``state[1]`` (rad/s), gravity ``gravity`` m/s^2 along -z: the recursive Newton-Euler algorithm on fixed-base
    trees of revolute and fixed joints (what PyBullet's ``calculateInverseDynamics`` gives, in one call for
    every tree and without its per-call conversions).

    Per link ``i`` (L links, parents before children; ``parent`` -1: a fixed, unrotated base): its joint's origin
    ``origin_pos`` (L, 3) m and rotation ``origin_rot`` (L, 3, 3) in the parent's frame, its unit ``axis`` (L, 3)
    in its own frame, ``slot`` (L,) the column of ``state`` of its angle (-1: a fixed joint), ``mass`` (L,) kg,
    ``com`` (L, 3) m and ``inertia`` (L, 3, 3) kg m^2 about the COM, in its frame. Torques of columns no link
    drives are 0."""
    n_links = parent.shape[0]
    rot = np.empty((n_links, 3, 3))  # link frame in its parent's frame
    w = np.empty((n_links, 3))  # angular velocity, link frame
    wd = np.empty((n_links, 3))  # angular acceleration, link frame
    acc = np.empty((n_links, 3))  # linear acceleration of the link origin (gravity as the base rising), link frame
    force = np.empty((n_links, 3))  # force on the link from its parent, link frame
    moment = np.empty((n_links, 3))  # moment about the link origin from its parent, link frame
    for i in range(n_links):
        k = slot[i]
        angle = state[0, k] if k >= 0 else 0.0
        rate = state[1, k] if k >= 0 else 0.0
        accel = state[2, k] if k >= 0 else 0.0
        ux, uy, uz = axis[i, 0], axis[i, 1], axis[i, 2]
        c, s_ = math.cos(angle), math.sin(angle)
        t = 1.0 - c
        j00, j01, j02 = c + t * ux * ux, t * ux * uy - s_ * uz, t * ux * uz + s_ * uy
        j10, j11, j12 = t * ux * uy + s_ * uz, c + t * uy * uy, t * uy * uz - s_ * ux
        j20, j21, j22 = t * ux * uz - s_ * uy, t * uy * uz + s_ * ux, c + t * uz * uz
        o = origin_rot[i]
        for r in range(3):
            rot[i, r, 0] = o[r, 0] * j00 + o[r, 1] * j10 + o[r, 2] * j20
            rot[i, r, 1] = o[r, 0] * j01 + o[r, 1] * j11 + o[r, 2] * j21
            rot[i, r, 2] = o[r, 0] * j02 + o[r, 1] * j12 + o[r, 2] * j22
        p = parent[i]
        if p < 0:
            wx = wy = wz = 0.0
            bx = by = bz = 0.0
            ax, ay, az = 0.0, 0.0, gravity
        else:
            wx, wy, wz = w[p, 0], w[p, 1], w[p, 2]
            bx, by, bz = wd[p, 0], wd[p, 1], wd[p, 2]
            ax, ay, az = acc[p, 0], acc[p, 1], acc[p, 2]
        px, py, pz = origin_pos[i, 0], origin_pos[i, 1], origin_pos[i, 2]
        # the parent's acceleration at this joint's origin: a + wd x r + w x (w x r)
        vx, vy, vz = wy * pz - wz * py, wz * px - wx * pz, wx * py - wy * px
        ax += by * pz - bz * py + wy * vz - wz * vy
        ay += bz * px - bx * pz + wz * vx - wx * vz
        az += bx * py - by * px + wx * vy - wy * vx
        # into this link's frame (the transpose of its rotation), then its own joint's motion
        R = rot[i]
        wx, wy, wz = (R[0, 0] * wx + R[1, 0] * wy + R[2, 0] * wz, R[0, 1] * wx + R[1, 1] * wy + R[2, 1] * wz,
                      R[0, 2] * wx + R[1, 2] * wy + R[2, 2] * wz)
        bx, by, bz = (R[0, 0] * bx + R[1, 0] * by + R[2, 0] * bz, R[0, 1] * bx + R[1, 1] * by + R[2, 1] * bz,
                      R[0, 2] * bx + R[1, 2] * by + R[2, 2] * bz)
        ax, ay, az = (R[0, 0] * ax + R[1, 0] * ay + R[2, 0] * az, R[0, 1] * ax + R[1, 1] * ay + R[2, 1] * az,
                      R[0, 2] * ax + R[1, 2] * ay + R[2, 2] * az)
        sx, sy, sz = ux * rate, uy * rate, uz * rate
        bx += ux * accel + wy * sz - wz * sy
        by += uy * accel + wz * sx - wx * sz
        bz += uz * accel + wx * sy - wy * sx
        wx, wy, wz = wx + sx, wy + sy, wz + sz
        w[i, 0], w[i, 1], w[i, 2] = wx, wy, wz
        wd[i, 0], wd[i, 1], wd[i, 2] = bx, by, bz
        acc[i, 0], acc[i, 1], acc[i, 2] = ax, ay, az
        # the centre of mass's acceleration, and the force and moment (about the link origin) it takes
        cx, cy, cz = com[i, 0], com[i, 1], com[i, 2]
        vx, vy, vz = wy * cz - wz * cy, wz * cx - wx * cz, wx * cy - wy * cx
        m = mass[i]
        fx = m * (ax + by * cz - bz * cy + wy * vz - wz * vy)
        fy = m * (ay + bz * cx - bx * cz + wz * vx - wx * vz)
        fz = m * (az + bx * cy - by * cx + wx * vy - wy * vx)
        inn = inertia[i]
        hx = inn[0, 0] * wx + inn[0, 1] * wy + inn[0, 2] * wz
        hy = inn[1, 0] * wx + inn[1, 1] * wy + inn[1, 2] * wz
        hz = inn[2, 0] * wx + inn[2, 1] * wy + inn[2, 2] * wz
        force[i, 0], force[i, 1], force[i, 2] = fx, fy, fz
        moment[i, 0] = inn[0, 0] * bx + inn[0, 1] * by + inn[0, 2] * bz + wy * hz - wz * hy + cy * fz - cz * fy
        moment[i, 1] = inn[1, 0] * bx + inn[1, 1] * by + inn[1, 2] * bz + wz * hx - wx * hz + cz * fx - cx * fz
        moment[i, 2] = inn[2, 0] * bx + inn[2, 1] * by + inn[2, 2] * bz + wx * hy - wy * hx + cx * fy - cy * fx
    tau = np.zeros(state.shape[1])
    for i in range(n_links - 1, -1, -1):  # children before parents: each passes its load on to its parent
        if slot[i] >= 0:
            tau[slot[i]] = axis[i, 0] * moment[i, 0] + axis[i, 1] * moment[i, 1] + axis[i, 2] * moment[i, 2]
        p = parent[i]
        if p >= 0:
            R = rot[i]
            fx = R[0, 0] * force[i, 0] + R[0, 1] * force[i, 1] + R[0, 2] * force[i, 2]
            fy = R[1, 0] * force[i, 0] + R[1, 1] * force[i, 1] + R[1, 2] * force[i, 2]
            fz = R[2, 0] * force[i, 0] + R[2, 1] * force[i, 1] + R[2, 2] * force[i, 2]
            px, py, pz = origin_pos[i, 0], origin_pos[i, 1], origin_pos[i, 2]
            force[p, 0] += fx
            force[p, 1] += fy
            force[p, 2] += fz
            for r in range(3):
                moment[p, r] += R[r, 0] * moment[i, 0] + R[r, 1] * moment[i, 1] + R[r, 2] * moment[i, 2]
            moment[p, 0] += py * fz - pz * fy
            moment[p, 1] += pz * fx - px * fz
            moment[p, 2] += px * fy - py * fx
    return tau


@njit(cache=True)
def hermite(t: float, t0: float, t1: float, p0: np.ndarray, p1: np.ndarray, v0: np.ndarray,
            v1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cubic Hermite value and rate at time ``t`` (s) between knots at ``t0`` and ``t1`` with values
    ``p0``, ``p1`` and rates ``v0``, ``v1`` (per second)."""
    h = t1 - t0
    s = (t - t0) / h
    s2, s3 = s * s, s * s * s
    m0, m1 = v0 * h, v1 * h
    pos = (2 * s3 - 3 * s2 + 1) * p0 + (s3 - 2 * s2 + s) * m0 + (-2 * s3 + 3 * s2) * p1 + (s3 - s2) * m1
    vel = ((6 * s2 - 6 * s) * p0 + (3 * s2 - 4 * s + 1) * m0 + (-6 * s2 + 6 * s) * p1 + (3 * s2 - 2 * s) * m1) / h
    return pos, vel


@njit(cache=True)
def hermite_stray(times: np.ndarray, values: np.ndarray, velocities: np.ndarray, t_from: float, t_to: float,
                  step: float, p0: np.ndarray) -> float:
    """Farthest (m) the cubic Hermite through knots at ``times`` (n,) s (n >= 2) with values (n, d) and rates
    (n, d) per second comes from ``p0`` (d,) strictly between ``t_from`` and ``t_to`` (s): sampled every ``step``
    seconds from ``t_from`` and at every knot between (outside the knots the end knot is held, as
    ``targets.Track.sample`` does)."""
    n, d = values.shape
    far = 0.0
    for i in range(n):  # the knots between: their own values
        if t_from < times[i] < t_to:
            far = max(far, math.sqrt(np.sum((values[i] - p0) ** 2)))
    k = 0
    t = t_from + step
    while t < t_to:
        while k < n - 2 and times[k + 1] <= t:
            k += 1
        h = times[k + 1] - times[k]
        s = min(max((t - times[k]) / h, 0.0), 1.0)
        s2, s3 = s * s, s * s * s
        a, b, c, e = 2 * s3 - 3 * s2 + 1, (s3 - 2 * s2 + s) * h, 3 * s2 - 2 * s3, (s3 - s2) * h
        dist = 0.0
        for j in range(d):
            x = a * values[k, j] + b * velocities[k, j] + c * values[k + 1, j] + e * velocities[k + 1, j] - p0[j]
            dist += x * x
        far = max(far, math.sqrt(dist))
        t += step
    return far


# ---------------------------------------------------------------------- swinging cymbals


@njit(cache=True)
def _fade(x: float, full: float, zero: float) -> float:
    """1 up to ``full``, 0 from ``zero`` on, a smoothstep between (either order of the two)."""
    s = min(max((x - full) / (zero - full), 0.0), 1.0)
    return 1.0 - s * s * (3.0 - 2.0 * s)


@njit(cache=True)
def swing_displacement(points: np.ndarray, centre: np.ndarray, rotation: np.ndarray, radius: np.ndarray,
                       angles: np.ndarray, reach: float, above: float, below: float) -> np.ndarray:
    """How far (P, 3) m points (P, 3) m aimed at cymbals move when each cymbal carries them along its swing.

    Cymbal ``c`` pivots about ``centre[c]`` (3,) m, its rest frame ``rotation[c]`` (3, 3) (z: the plate's
    normal), turned now by ``Rx(angles[c, 0]) Ry(angles[c, 1])`` (rad) in that frame. A point over the plate
    (within ``radius[c]`` of its axis and between ``below`` m under and ``above`` m over it) moves rigidly with
    the plate; the share fades smoothly to nothing ``reach`` m beyond the rim and as far again beyond
    ``above`` and ``below``, so a path leaving a cymbal's neighbourhood stays continuous.
    """
    out = np.zeros_like(points)
    local = np.empty(3)
    moved = np.empty(3)
    for c in range(centre.shape[0]):
        a, b = angles[c, 0], angles[c, 1]
        if abs(a) < 1e-5 and abs(b) < 1e-5:
            continue
        ca, sa, cb, sb = math.cos(a), math.sin(a), math.cos(b), math.sin(b)
        rot = rotation[c]
        for i in range(points.shape[0]):
            for k in range(3):  # the point in the cymbal's rest frame
                local[k] = rot[0, k] * (points[i, 0] - centre[c, 0]) + rot[1, k] * (points[i, 1] - centre[c, 1]) \
                    + rot[2, k] * (points[i, 2] - centre[c, 2])
            w = _fade(math.hypot(local[0], local[1]), radius[c], radius[c] + reach)
            if w == 0.0:
                continue
            h = local[2]
            w *= _fade(h, above, above + reach) if h > 0.0 else _fade(-h, below, below + reach)
            if w == 0.0:
                continue
            # Rx(a) Ry(b) local - local, in the rest frame
            moved[0] = cb * local[0] + sb * local[2] - local[0]
            moved[1] = sa * sb * local[0] + ca * local[1] - sa * cb * local[2] - local[1]
            moved[2] = -ca * sb * local[0] + sa * local[1] + ca * cb * local[2] - local[2]
            for k in range(3):
                out[i, k] += w * (rot[k, 0] * moved[0] + rot[k, 1] * moved[1] + rot[k, 2] * moved[2])
    return out


@njit(cache=True)
def stick_under_plate(bead: np.ndarray, wrist: np.ndarray, aim: np.ndarray, centre: np.ndarray,
                      rotation: np.ndarray, radius: np.ndarray, angles: np.ndarray, side: np.ndarray,
                      fractions: np.ndarray, margin: float, clear: float) -> int:
    """The first cymbal a stick is under and would press from below, or -1 (every argument in metres, radians).

    The stick: points ``fractions`` (S,) of the way from ``wrist`` (3,) to ``bead`` (3,), moving as the bead would
    to ``aim`` (3,). Cymbal ``c``'s plate: in the plane z = 0 of its frame, ``rotation[c]`` (3, 3) about
    ``centre[c]`` (3,) turned by ``Rx(angles[c, 0]) Ry(angles[c, 1])`` in that frame, ``radius[c]`` wide. A point
    is under it within ``margin`` beyond its rim; it would be pressed when the move brings it within
    ``clear`` of the plate, the aim not that far or more below it.

    ``side`` (C,) int, updated: the side of each plate the bead came to it from, set as it comes within
    ``margin`` of the rim (1 above the plane, -1 below), 0 again beyond ``clear``. A
    bead that came from above is never under: striking the plate, it passes below the plane the hinge's angles read
    4 ms before give. Compiled: called for each hand at every control update.
    """
    found = -1
    local = np.empty((3, 3))  # aim, bead, wrist in the plate's frame
    for c in range(centre.shape[0]):
        ca, sa = math.cos(angles[c, 0]), math.sin(angles[c, 0])
        cb, sb = math.cos(angles[c, 1]), math.sin(angles[c, 1])
        rot = rotation[c]
        for i, point in enumerate((aim, bead, wrist)):
            dx, dy, dz = point[0] - centre[c, 0], point[1] - centre[c, 1], point[2] - centre[c, 2]
            x = rot[0, 0] * dx + rot[1, 0] * dy + rot[2, 0] * dz  # the rest frame's coordinates
            y = rot[0, 1] * dx + rot[1, 1] * dy + rot[2, 1] * dz
            z = rot[0, 2] * dx + rot[1, 2] * dy + rot[2, 2] * dz
            y, z = ca * y + sa * z, -sa * y + ca * z  # Rx(a)^T then Ry(b)^T
            x, z = cb * x - sb * z, sb * x + cb * z
            local[i, 0], local[i, 1], local[i, 2] = x, y, z
        rho = math.hypot(local[1, 0], local[1, 1])
        if rho > radius[c] + clear:
            side[c] = 0
        elif side[c] == 0 and rho < radius[c] + margin:
            side[c] = 1 if local[1, 2] >= 0.0 else -1
        if found >= 0 or side[c] == 1 or local[0, 2] < -clear:
            continue
        rise = local[0, 2] - local[1, 2]
        for f in fractions:
            z = local[2, 2] + f * (local[1, 2] - local[2, 2])
            if z < 0.0 and z + rise > -clear:
                x = local[2, 0] + f * (local[1, 0] - local[2, 0])
                y = local[2, 1] + f * (local[1, 1] - local[2, 1])
                if math.hypot(x, y) < radius[c] + margin:
                    found = c
                    break
    return found
