"""The percussionist loaded in a world: index maps, state access, the seat on the throne, kinematics.

:class:`Body` turns the generated :class:`~services.physics.character.CharacterModel`
into PyBullet multibodies (the trunk with arms and sticks, and each leg; see
character.py) whose bases are fixed on the throne, and gives vectorised access
in DOF order (57,) to joint angles and velocities, and the geometric Jacobian
of the effectors.

Links are numbered across the parts ("global" link indices): the trunk's links
keep their PyBullet indices (0 ... 46, its base ``seat`` is -1), each leg's
follow. :attr:`Body.link_ref` turns a global index into the (body id, link)
pair PyBullet calls take.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import chain
from operator import itemgetter
from typing import Any, NamedTuple

import numpy as np

from common.character import JOINT_LINKS, JOINTS
from common.quiet_pybullet import pybullet as p
from services.physics.character import CharacterModel
from services.physics.kernels import forward_kinematics, jacobian
from services.physics.urdf import Joint, load_robot
from services.physics.world import World, rotation_matrix

LIMBS = ("left_hand", "right_hand", "left_foot", "right_foot")
_ANGLE, _RATE = itemgetter(0), itemgetter(1)
"""A joint state's angle and rate (``getJointStates`` rows)."""


@dataclass(frozen=True)
class LoadedPart:
    """One multibody of the body in the world.

    ``id``: PyBullet body id; ``offset``: its global link index of local link 0; ``links``: its link count;
    ``state_joints``: its local joints in the order it is read and commanded (its DOF in DOF order, then its
    passive joints); ``state_slots``: where those joints stand in :attr:`Body.state_joints` order;
    ``movable``: its revolute joints in PyBullet's own order (the columns of its mass matrix).
    """

    id: int
    offset: int
    links: int
    state_joints: list[int]
    state_slots: np.ndarray
    movable: list[int]


class DynamicsTree(NamedTuple):
    """Fixed-base trees of revolute and fixed joints, per link (L links, parents before children), as
    :func:`kernels.inverse_dynamics` takes them (see there for units and frames)."""

    parent: np.ndarray
    origin_pos: np.ndarray
    origin_rot: np.ndarray
    axis: np.ndarray
    slot: np.ndarray
    mass: np.ndarray
    com: np.ndarray
    inertia: np.ndarray


def consecutive_runs(lengths: list[int]) -> list[tuple[int, int]]:
    """(start, stop) of runs of the given lengths laid one after another: [2, 3] -> [(0, 2), (2, 5)]."""
    runs = []
    start = 0
    for length in lengths:
        runs.append((start, start + length))
        start += length
    return runs


class Body:
    """A generated character in a :class:`World`, its seat fixed at ``seat_position`` (metres).

    ``floating_base``: load the trunk's base as a free body pinned to the throne by a fixed constraint instead
    of a fixed base. The body moves the same; PyBullet's stable PD needs it (it silently fails to track on a
    fixed base), but the constraint's rows cost about a fifth of every step. The legs keep fixed bases: PyBullet's
    stable PD on a pinned leg gave NaN at its first step about one run in seven (the same inputs otherwise
    tracked), so the stable-PD mode drives the legs with explicit torques (:meth:`Controller.apply`).
    """

    def __init__(self, world: World, model: CharacterModel, seat_position: tuple[float, float, float],
                 floating_base: bool = False) -> None:
        self.world = world
        self.model = model
        self.floating_base = floating_base
        c = world.client
        self.ids: list[int] = []
        self.pins: list[int] = []
        self.joint_index: dict[str, int] = {}
        """Joint name -> global index of its child link (a joint and its child link share PyBullet's index)."""
        self.link_index: dict[str, int] = {"seat": -1}
        self.link_ref: dict[int, tuple[int, int]] = {}
        """Global link index -> (body id, link index in that body); a leg's base is not a global link."""
        self._parent: dict[int, int] = {}
        offset = 0
        bases: list[tuple[int, int]] = []
        self.base_positions: list[tuple[float, ...]] = []
        """Each part's base position as loaded, metres (world frame, unrotated)."""
        for k, spec in enumerate(model.parts):
            base = tuple(float(s + o) for s, o in zip(seat_position, spec.base_offset_m, strict=True))
            floating = floating_base and k == 0  # the trunk only (see the class docstring)
            body = load_robot(c, spec.robot, base, (0.0, 0.0, 0.0, 1.0),  # type: ignore[arg-type]
                              fixed_base=not floating, flags=p.URDF_USE_INERTIA_FROM_FILE)
            self.ids.append(body)
            self.base_positions.append(base)
            if floating:
                pin = c.createConstraint(body, -1, -1, -1, p.JOINT_FIXED, [0, 0, 0], [0, 0, 0], list(base))
                c.changeConstraint(pin, maxForce=1e5)
                self.pins.append(pin)
            n = c.getNumJoints(body)
            for j in range(n):
                info = c.getJointInfo(body, j)
                self.joint_index[info[1].decode()] = offset + j
                self.link_index[info[12].decode()] = offset + j
                self.link_ref[offset + j] = (body, j)
                self._parent[offset + j] = -1 if info[16] < 0 else offset + info[16]
                c.setJointMotorControl2(body, j, p.VELOCITY_CONTROL, force=0.0)
                c.changeDynamics(body, j, linearDamping=0.0, angularDamping=0.0, jointDamping=0.0)
            bases.append((body, offset))
            offset += n
        self.id = self.ids[0]
        """The trunk's body id (its links' global indices are its own PyBullet indices)."""
        self.link_ref[-1] = (self.id, -1)
        self.dofs = np.array([self.joint_index[n] for n in model.dof_names], dtype=int)
        self.dof_list = [int(j) for j in self.dofs]
        self.passive = [self.joint_index[n] for n in model.passive]
        self.state_joints = self.dof_list + self.passive
        """The 57 DOF then the passive joints (global indices): the order of :meth:`full_state` and of the torques
        sent."""
        self.parts: list[LoadedPart] = []
        for body, start in bases:
            n = c.getNumJoints(body)
            slots = [k for k, j in enumerate(self.state_joints) if start <= j < start + n]
            movable = [j for j in range(n) if c.getJointInfo(body, j)[2] == p.JOINT_REVOLUTE]
            self.parts.append(LoadedPart(body, start, n, [self.state_joints[k] - start for k in slots],
                                         np.array(slots, dtype=int), movable))
        self._read_order = np.concatenate([part.state_slots for part in self.parts])
        self._from_read = np.argsort(self._read_order)
        """Index that puts the parts' readings (concatenated) into :attr:`state_joints` order."""
        self._read_runs = consecutive_runs([len(part.state_slots) for part in self.parts])
        """Each part's (start, stop) in the read order."""
        self._send = np.zeros(len(self.state_joints))
        """Buffer of the torques sent, in :attr:`state_joints` order."""
        self.lower = np.array([self._joint_info(j)[8] for j in self.dof_list])
        self.upper = np.array([self._joint_info(j)[9] for j in self.dof_list])
        self.torque_limit = np.array([model.torque_limits[n] for n in model.dof_names])
        self.effector_links = {limb: self.link_index[model.effectors[limb]] for limb in LIMBS}
        self.tip_links = {limb: self.link_index[model.tips[limb]] for limb in LIMBS}
        # ancestors: which DOF move which link
        self._dof_pos = {j: k for k, j in enumerate(self.dof_list)}
        self.chain_mask = np.array([self.mask_of(self.effector_links[limb]) for limb in LIMBS])
        # forward kinematics of the 19 joints in numba (kernels.forward_kinematics): each joint's origin in its
        # parent's child frame, the bases on the throne, the effectors in their carriers' frames
        self._fk = self._kinematic_tree(seat_position)
        joint_children = [int(self.dofs[3 * k + 2]) for k in range(len(self.dofs) // 3)]
        self._frame_row = {link: row for row, link in enumerate(joint_children)}
        self._frame_row |= {self.effector_links[limb]: len(joint_children) + k for k, limb in enumerate(LIMBS)}
        self._full_states: list[tuple[Any, ...]] | None = None
        self._frame_pos: np.ndarray | None = None
        self._link_pos: np.ndarray | None = None
        self.last_qd = np.zeros(len(self.state_joints))
        self.update()

    def _joint_info(self, link: int) -> tuple[Any, ...]:
        body, j = self.link_ref[link]
        info: tuple[Any, ...] = self.world.client.getJointInfo(body, j)
        return info

    def set_limits(self, limits: dict[str, tuple[float, float]]) -> None:
        """Change the DOF's joint limits (DOF name -> (lower, upper), radians) in PyBullet and in :attr:`lower`
        and :attr:`upper` (PyBullet's ``getJointInfo`` keeps reporting the URDF's; its solver uses these)."""
        c = self.world.client
        for k, (name, link) in enumerate(zip(self.model.dof_names, self.dof_list, strict=True)):
            if name in limits:
                lower, upper = limits[name]
                body, j = self.link_ref[link]
                c.changeDynamics(body, j, jointLowerLimit=lower, jointUpperLimit=upper)
                self.lower[k], self.upper[k] = lower, upper

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
        q, qd, _, _ = self.full_state()
        return q, qd

    def passive_state(self) -> tuple[np.ndarray, np.ndarray]:
        """Angles (P,) radians and velocities (P,) rad/s of the passive joints (the sticks' fulcrums)."""
        _, _, pq, pqd = self.full_state()
        return pq, pqd

    def full_state(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`state` and :meth:`passive_state` in one read per part: (57,), (57,), (P,), (P,)."""
        c = self.world.client
        states = [s for part in self.parts for s in c.getJointStates(part.id, part.state_joints)]
        m = len(states)
        # angles then velocities in one flat read, put into state order (each row contiguous)
        both = np.fromiter(chain(map(_ANGLE, states), map(_RATE, states)), float, 2 * m).reshape(2, m)
        both = both[:, self._from_read]
        q, qd = both[0], both[1]
        self.last_qd = qd
        """Every state joint's velocity (rad/s) at the last :meth:`full_state`, in ``state_joints`` order."""
        n = len(self.dof_list)
        return q[:n], qd[:n], q[n:], qd[n:]

    def trunk_velocities(self) -> np.ndarray:
        """The trunk's joint velocities (rad/s) from the last :meth:`full_state`, in its ``state_joints`` order
        (the sticks are on the trunk: the contact tracker's approach velocities)."""
        return self.last_qd[self.parts[0].state_slots]

    def send_torques(self, tau: np.ndarray, passive_tau: np.ndarray | None = None) -> None:
        """Apply joint torques (N m) for the next step (PyBullet clears them after every step): ``tau`` in
        :attr:`state_joints` order (57 DOF then the passive joints), or the 57 DOF's with ``passive_tau`` the
        passive joints'."""
        c = self.world.client
        if passive_tau is not None:
            n = len(tau)
            self._send[:n] = tau
            self._send[n:] = passive_tau
            tau = self._send
        forces = tau[self._read_order].tolist()  # one conversion, then each part's run of it
        for part, (start, stop) in zip(self.parts, self._read_runs, strict=True):
            c.setJointMotorControlArray(part.id, part.state_joints, p.TORQUE_CONTROL, forces=forces[start:stop])

    def set_state(self, q: np.ndarray, qd: np.ndarray | None = None) -> None:
        """Teleport the joints (resets, tests and the kinematic IK); velocities default to zero."""
        c = self.world.client
        n = len(self.dof_list)
        values = np.zeros(len(self.state_joints))
        rates = np.zeros(len(self.state_joints))
        values[:n] = q
        if qd is not None:
            rates[:n] = qd
        for part in self.parts:
            c.resetJointStatesMultiDof(part.id, part.state_joints,
                                       targetValues=[[float(a)] for a in values[part.state_slots]],
                                       targetVelocities=[[float(v)] for v in rates[part.state_slots]])
        self.update(values[:n])

    def restore_bases(self) -> None:
        """Put every part's base back where it was loaded, at rest (after a divergence: a fixed base's pose reads
        NaN once its joints have)."""
        c = self.world.client
        for body, base in zip(self.ids, self.base_positions, strict=True):
            c.resetBasePositionAndOrientation(body, base, (0.0, 0.0, 0.0, 1.0))
            c.resetBaseVelocity(body, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))

    def dynamics_tree(self) -> DynamicsTree:
        """The arrays of :func:`kernels.inverse_dynamics` for every part of the body (each a fixed-base tree,
        parents before children), from the generated model, its revolute joints' columns in
        :attr:`state_joints` order."""
        slot_of = {j: k for k, j in enumerate(self.state_joints)}
        rows: list[tuple[int, Joint, int]] = []  # (parent row, joint, state slot)
        for spec in self.model.parts:
            joints_from: dict[str, list[Joint]] = {}
            for joint in spec.robot.joints:
                joints_from.setdefault(joint.parent, []).append(joint)
            row_of = {spec.robot.links[0].name: -1}
            todo = [spec.robot.links[0].name]
            while todo:
                link = todo.pop(0)
                for joint in joints_from.get(link, []):
                    if joint.kind not in ("revolute", "continuous", "fixed"):
                        raise ValueError(f"joint {joint.name}: inverse dynamics takes revolute and fixed joints")
                    slot = -1 if joint.kind == "fixed" else slot_of[self.joint_index[joint.name]]
                    row_of[joint.child] = len(rows)
                    rows.append((row_of[link], joint, slot))
                    todo.append(joint.child)
        inertials = {lk.name: lk.inertial for spec in self.model.parts for lk in spec.robot.links}
        n = len(rows)
        tree = DynamicsTree(
            parent=np.array([r[0] for r in rows], dtype=np.int64),
            origin_pos=np.array([r[1].xyz for r in rows], dtype=float),
            origin_rot=np.array([rotation_matrix(p.getQuaternionFromEuler(r[1].rpy)) for r in rows]),
            axis=np.zeros((n, 3)), slot=np.array([r[2] for r in rows], dtype=np.int64),
            mass=np.zeros(n), com=np.zeros((n, 3)), inertia=np.zeros((n, 3, 3)))
        for k, (_, joint, slot_k) in enumerate(rows):
            if slot_k >= 0:
                tree.axis[k] = np.asarray(joint.axis, dtype=float) / np.linalg.norm(joint.axis)
            inertial = inertials[joint.child]
            ixx, iyy, izz, ixy, ixz, iyz = inertial.inertia
            tree.mass[k], tree.com[k] = inertial.mass, inertial.com
            tree.inertia[k] = ((ixx, ixy, ixz), (ixy, iyy, iyz), (ixz, iyz, izz))
        return tree

    def _kinematic_tree(self, seat_position: tuple[float, float, float]) -> tuple[np.ndarray, ...]:
        """The arrays of :func:`kernels.forward_kinematics` for this body (see :meth:`update`)."""
        joints = {j.name: j for spec in self.model.parts for j in spec.robot.joints}
        base_of = {spec.robot.links[0].name: np.add(seat_position, spec.base_offset_m) for spec in self.model.parts}
        carrier = {JOINT_LINKS[joint][1]: k for k, joint in enumerate(JOINTS)}
        parent = np.full(len(JOINTS), -1, dtype=np.int64)
        offset = np.zeros((len(JOINTS), 3))
        base_pos = np.zeros((len(JOINTS), 3))
        for k, joint in enumerate(JOINTS):
            first = joints[f"{joint}_x"]
            if any(joints[f"{joint}_{axis}"].rpy != (0.0, 0.0, 0.0) for axis in "xyz"):
                raise ValueError(f"joint {joint}: forward kinematics assumes no rotation offset")
            offset[k] = first.xyz
            if first.parent in carrier:
                parent[k] = carrier[first.parent]
            else:
                base_pos[k] = base_of[first.parent]
        effector_joint = np.zeros(len(LIMBS), dtype=np.int64)
        effector_offset = np.zeros((len(LIMBS), 3))
        for e, limb in enumerate(LIMBS):
            fixed = next(j for j in joints.values() if j.child == self.model.effectors[limb])
            effector_joint[e] = carrier[fixed.parent]
            effector_offset[e] = fixed.xyz
        base_rot = np.tile(np.eye(3), (len(JOINTS), 1, 1))
        return parent, offset, base_pos, base_rot, effector_joint, effector_offset

    def update(self, q: np.ndarray | None = None) -> None:
        """Forward kinematics of the joints and effectors at the DOF angles ``q`` (57,) radians (default: read
        them): :attr:`dof_pos`, :attr:`dof_axes`, :attr:`effector_pos` (call at the start of a control update;
        the kinematics use them). No PyBullet call with a fixed base (the bases never move)."""
        if q is None:
            q = self.state()[0]
        parent, offset, base_pos, base_rot, effector_joint, effector_offset = self._fk
        if self.floating_base:  # the trunk's pinned base may give a little: use where it is now
            pos, quat = self.world.client.getBasePositionAndOrientation(self.id)  # its inertial frame is its own
            base_pos[0] = pos
            base_rot[0] = rotation_matrix(quat)
        self.dof_pos, self.dof_axes, self._joint_pos, self.effector_pos = forward_kinematics(
            np.ascontiguousarray(q, dtype=float), parent, offset, base_pos, base_rot, effector_joint,
            effector_offset)
        self._frame_pos = None
        self._full_states = None
        self._link_pos = None

    def _all_links(self, field: int) -> np.ndarray:
        """One vector field (links, 3) of every link's state in this state (``getLinkStates``: 0 the centre of
        mass, 4 the link frame's origin), the states read once after an update."""
        if self._full_states is None:
            c = self.world.client
            self._full_states = list(chain.from_iterable(
                c.getLinkStates(part.id, list(range(part.links)), computeForwardKinematics=1) for part in self.parts))
        n = len(self._full_states)
        return np.fromiter(chain.from_iterable(s[field] for s in self._full_states), float, 3 * n).reshape(n, 3)

    @property
    def link_pos(self) -> np.ndarray:
        """Every link's frame origin (links, 3) metres in this state (read when first asked after an update)."""
        if self._link_pos is None:
            self._link_pos = self._all_links(4)
        return self._link_pos

    @property
    def frame_pos(self) -> np.ndarray:
        """The 19 joints' frame origins then the 4 effectors (23, 3) metres at the last :meth:`update`."""
        if self._frame_pos is None:
            self._frame_pos = np.concatenate([self._joint_pos, self.effector_pos])
        return self._frame_pos

    def position(self, link: int) -> np.ndarray:
        """A link's frame origin (3,) metres at the last :meth:`update`."""
        row = self._frame_row.get(link)
        if row is None:
            return self.link_pos[link]
        joints = len(self._joint_pos)  # a row of frame_pos, without building it
        return self._joint_pos[row] if row < joints else self.effector_pos[row - joints]

    def kinematics(self, links: list[int] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Positions (L, 3) metres and Jacobians (L, 3, 57) of links (default: the four effectors, in LIMBS
        order), from the poses read by :meth:`update`.

        Geometric Jacobian of revolute DOF: column j of link e is ``axis_j x (p_e - p_j)`` when DOF j is an
        ancestor of e (else 0).
        """
        if links is None:
            eff, mask = self.effector_pos, self.chain_mask
        else:
            eff = np.array([self.position(int(k)) for k in links]).reshape(-1, 3)
            mask = np.array([self.mask_of(int(k)) for k in links]).reshape(len(eff), -1)
        return eff, jacobian(eff, self.dof_pos, self.dof_axes, mask)

    def effector_positions(self, actual: bool = True) -> np.ndarray:
        """(4, 3) metres, in LIMBS order: the actual stick tips (``actual``) or the controlled aim points."""
        links = [(self.tip_links if actual else self.effector_links)[limb] for limb in LIMBS]
        return np.array([self.link_pose(link)[0] for link in links])

    def link_pose(self, link: int) -> tuple[np.ndarray, np.ndarray]:
        """World position (3,) metres and quaternion (4,) xyzw of a link (global index; -1: the seat)."""
        return self.world.link_frame(*self.link_ref[link])

