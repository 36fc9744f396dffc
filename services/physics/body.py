"""The percussionist loaded in a world: index maps, state access, the seat on the throne, kinematics.

:class:`Body` turns the generated :class:`~services.physics.character.CharacterModel`
into a PyBullet multibody whose base (the seat) is fixed on the throne, and
gives vectorised access in DOF order (57,) to joint angles and velocities,
and the geometric Jacobian of the effectors.
"""

from __future__ import annotations

from itertools import chain
from typing import Any

import numpy as np
import pybullet as p

from services.physics.character import CharacterModel
from services.physics.urdf import load_robot
from services.physics.world import World

LIMBS = ("left_hand", "right_hand", "left_foot", "right_foot")


class Body:
    """A generated character in a :class:`World`, its seat fixed at ``seat_position`` (metres).

    ``floating_base``: load the base as a free body pinned to the seat by a fixed constraint instead of a
    fixed base. The body moves the same; PyBullet's stable PD needs it (it silently fails to track on a
    fixed base), but the constraint's six rows cost about a fifth of every step.
    """

    def __init__(self, world: World, model: CharacterModel, seat_position: tuple[float, float, float],
                 floating_base: bool = False) -> None:
        self.world = world
        self.model = model
        self.floating_base = floating_base
        c = world.client
        self.id = load_robot(c, model.robot, seat_position, (0.0, 0.0, 0.0, 1.0), fixed_base=not floating_base,
                             flags=p.URDF_USE_INERTIA_FROM_FILE)
        self.pin: int | None = None
        if floating_base:
            self.pin = c.createConstraint(self.id, -1, -1, -1, p.JOINT_FIXED, [0, 0, 0], [0, 0, 0],
                                          list(seat_position))
            c.changeConstraint(self.pin, maxForce=1e5)
        self.joint_index: dict[str, int] = {}
        self.link_index: dict[str, int] = {"seat": -1}
        for j in range(c.getNumJoints(self.id)):
            info = c.getJointInfo(self.id, j)
            self.joint_index[info[1].decode()] = j
            self.link_index[info[12].decode()] = j
        self.dofs = np.array([self.joint_index[n] for n in model.dof_names], dtype=int)
        self.dof_list = [int(j) for j in self.dofs]
        self.passive = [self.joint_index[n] for n in model.passive]
        self.state_joints = self.dof_list + self.passive
        """The 57 DOF then the passive joints: the order of :meth:`full_state` and of the torques sent."""
        self.lower = np.array([c.getJointInfo(self.id, j)[8] for j in self.dof_list])
        self.upper = np.array([c.getJointInfo(self.id, j)[9] for j in self.dof_list])
        self.torque_limit = np.array([model.torque_limits[n] for n in model.dof_names])
        for j in range(c.getNumJoints(self.id)):
            c.setJointMotorControl2(self.id, j, p.VELOCITY_CONTROL, force=0.0)
            c.changeDynamics(self.id, j, linearDamping=0.0, angularDamping=0.0, jointDamping=0.0)
        self.effector_links = {limb: self.link_index[model.effectors[limb]] for limb in LIMBS}
        self.tip_links = {limb: self.link_index[model.tips[limb]] for limb in LIMBS}
        # ancestors: which DOF move which link
        self._parent = {j: c.getJointInfo(self.id, j)[16] for j in range(c.getNumJoints(self.id))}
        self._dof_pos = {j: k for k, j in enumerate(self.dof_list)}
        self.chain_mask = np.array([self.mask_of(self.effector_links[limb]) for limb in LIMBS])
        self.axes_local = np.array([c.getJointInfo(self.id, j)[13] for j in self.dof_list], dtype=float)
        self.all_links = list(range(c.getNumJoints(self.id)))
        self.effector_array = np.array([self.effector_links[limb] for limb in LIMBS], dtype=int)
        self._states: list[tuple[Any, ...]] = []
        self._link_com: np.ndarray | None = None
        self.update()

    def mask_of(self, link: int) -> np.ndarray:
        """(57,) bool: the DOF that move ``link``."""
        mask = np.zeros(len(self.dof_list), dtype=bool)
        while link >= 0:
            if link in self._dof_pos:
                mask[self._dof_pos[link]] = True
            link = self._parent[link]
        return mask

    # ------------------------------------------------------------------ state

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        """Joint angles (57,) radians and velocities (57,) rad/s."""
        states = self.world.client.getJointStates(self.id, self.dof_list)
        return np.array([s[0] for s in states]), np.array([s[1] for s in states])

    def passive_state(self) -> tuple[np.ndarray, np.ndarray]:
        """Angles (P,) radians and velocities (P,) rad/s of the passive joints (the sticks' fulcrums)."""
        states = self.world.client.getJointStates(self.id, self.passive)
        return np.array([s[0] for s in states]), np.array([s[1] for s in states])

    def full_state(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`state` and :meth:`passive_state` in one read: (57,), (57,), (P,), (P,)."""
        states = self.world.client.getJointStates(self.id, self.state_joints)
        m = len(states)
        q = np.fromiter((s[0] for s in states), float, m)
        qd = np.fromiter((s[1] for s in states), float, m)
        self.last_qd = qd
        """Every state joint's velocity (rad/s) at the last :meth:`full_state`, in ``state_joints`` order."""
        n = len(self.dof_list)
        return q[:n], qd[:n], q[n:], qd[n:]

    def set_state(self, q: np.ndarray, qd: np.ndarray | None = None) -> None:
        """Teleport the joints (resets, tests and the kinematic IK); velocities default to zero."""
        c = self.world.client
        vel = np.zeros(len(q)) if qd is None else qd
        joints = self.dof_list + self.passive
        values = [[float(a)] for a in q] + [[0.0]] * len(self.passive)
        rates = [[float(v)] for v in vel] + [[0.0]] * len(self.passive)
        c.resetJointStatesMultiDof(self.id, joints, targetValues=values, targetVelocities=rates)
        self.update()

    def update(self) -> None:
        """Read every link's pose once (call at the start of a control update; kinematics and gravity use it)."""
        c = self.world.client
        states = c.getLinkStates(self.id, self.all_links, computeForwardKinematics=1)
        n = len(states)
        # one flat read per field (np.array on a list of tuples is several times slower)
        self._states = states
        self._link_com = None
        self.link_pos = np.fromiter(chain.from_iterable(s[4] for s in states), float, 3 * n).reshape(n, 3)
        self.link_quat = np.fromiter(chain.from_iterable(s[5] for s in states), float, 4 * n).reshape(n, 4)
        self.dof_pos = self.link_pos[self.dofs]
        self.dof_axes = rotate(self.link_quat[self.dofs], self.axes_local)

    @property
    def link_com(self) -> np.ndarray:
        """Centres of mass (links, 3) metres at the last :meth:`update` (read when first asked)."""
        if self._link_com is None:
            n = len(self._states)
            self._link_com = np.fromiter(chain.from_iterable(s[0] for s in self._states), float, 3 * n).reshape(n, 3)
        return self._link_com

    def kinematics(self, links: list[int] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Positions (L, 3) metres and Jacobians (L, 3, 57) of links (default: the four effectors, in LIMBS
        order), from the poses read by :meth:`update`.

        Geometric Jacobian of revolute DOF: column j of link e is ``axis_j x (p_e - p_j)`` when DOF j is an
        ancestor of e (else 0).
        """
        if links is None:
            idx, mask = self.effector_array, self.chain_mask
        else:
            idx = np.asarray(links, dtype=int)
            mask = np.array([self.mask_of(int(k)) for k in idx])
        eff = self.link_pos[idx]
        d = eff[:, None, :] - self.dof_pos[None, :, :]  # (L, 57, 3)
        a = self.dof_axes[None, :, :]
        jac = np.stack([a[..., 1] * d[..., 2] - a[..., 2] * d[..., 1],
                        a[..., 2] * d[..., 0] - a[..., 0] * d[..., 2],
                        a[..., 0] * d[..., 1] - a[..., 1] * d[..., 0]], axis=1)  # (L, 3, 57)
        return eff, jac * mask[:, None, :]

    def effector_positions(self, actual: bool = True) -> np.ndarray:
        """(4, 3) metres, in LIMBS order: the actual stick tips (``actual``) or the controlled aim points."""
        c = self.world.client
        links = [(self.tip_links if actual else self.effector_links)[limb] for limb in LIMBS]
        states = c.getLinkStates(self.id, links, computeForwardKinematics=1)
        return np.array([s[4] for s in states])

    def link_pose(self, link: int) -> tuple[np.ndarray, np.ndarray]:
        return self.world.link_frame(self.id, link)


def rotate(quats: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors v (K, 3) by unit quaternions (K, 4) x y z w."""
    u = quats[:, :3]
    w = quats[:, 3:4]
    uv = np.stack([u[:, 1] * v[:, 2] - u[:, 2] * v[:, 1], u[:, 2] * v[:, 0] - u[:, 0] * v[:, 2],
                   u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]], axis=1)
    t = 2.0 * uv
    ut = np.stack([u[:, 1] * t[:, 2] - u[:, 2] * t[:, 1], u[:, 2] * t[:, 0] - u[:, 0] * t[:, 2],
                   u[:, 0] * t[:, 1] - u[:, 1] * t[:, 0]], axis=1)
    return v + w * t + ut
