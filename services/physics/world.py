"""The PyBullet world: one headless (DIRECT) client with Batteur's fixed settings.

Every physics object (character, sticks, kit) lives in one :class:`World`.
Each world owns its own PyBullet client, so several cores (or tests) can run
in one process without sharing state, and the same sequence of calls gives
bit-identical results (offline determinism).
"""

from __future__ import annotations

import functools
import math
import os
from dataclasses import dataclass
from typing import Any

import numpy as np

from common.quiet_pybullet import BulletClient
from common.quiet_pybullet import pybullet as p

Quat = tuple[float, float, float, float]
Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class WorldSettings:
    """Simulation settings.

    ``timestep_s``: fixed physics step, seconds (1 ms: 1 kHz).
    ``solver_iterations``: constraint solver iterations per step.
    ``substeps``: internal substeps per physics step (1: none); more substeps
    resolve stiff contacts better at a proportional cost.
    ``gravity``: m/s^2, along -z.
    """

    timestep_s: float = 1e-3
    solver_iterations: int = 50
    substeps: int = 1
    gravity: float = 9.81


class BoundClient(BulletClient):
    """A :class:`BulletClient` that binds each pybullet function to its client once.

    The stock client builds a ``functools.partial`` on every attribute access (about 1 us); the physics
    step makes dozens of calls, so the bound functions are kept.
    """

    def __init__(self) -> None:
        # a headless client connected without an options string: with one (the stock client passes ''), pybullet
        # prints "argv[0]=" to the process's stdout for every world, into every render's and tool's output
        self._shapes: dict = {}
        self._client = -1  # before anything can be interrupted: BulletClient.__del__ reads it
        self._pid = os.getpid()
        self._client = p.connect(p.DIRECT)

    def __getattr__(self, name: str) -> Any:
        attribute = super().__getattr__(name)
        if name != "disconnect" and isinstance(attribute, functools.partial):
            self.__dict__[name] = attribute
        return attribute


class World:
    """A PyBullet DIRECT client configured for Batteur (z up, fixed step)."""

    def __init__(self, settings: WorldSettings | None = None) -> None:
        self.settings = settings or WorldSettings()
        if not (0 < self.settings.timestep_s <= 0.01):
            raise ValueError(f"timestep_s must be in (0, 0.01] seconds, got {self.settings.timestep_s}")
        self.client: Any = BoundClient()
        self.client.setGravity(0.0, 0.0, -self.settings.gravity)
        self.client.setPhysicsEngineParameter(
            fixedTimeStep=self.settings.timestep_s,
            numSolverIterations=self.settings.solver_iterations,
            numSubSteps=self.settings.substeps,
            deterministicOverlappingPairs=1,
        )
        self.steps = 0

    @property
    def dt(self) -> float:
        return self.settings.timestep_s

    @property
    def time(self) -> float:
        """Simulated time since the world was made, seconds."""
        return self.steps * self.settings.timestep_s

    def step(self) -> None:
        self.client.stepSimulation()
        self.steps += 1

    def finite_state(self) -> bool:
        """Whether every body's base pose and velocity and every joint's angle and rate are finite numbers (a
        diverged simulation has NaN or inf in them). Reads the whole world: for a failure's diagnosis, not for
        every step."""
        c = self.client
        values: list[float] = []
        for k in range(c.getNumBodies()):
            body = c.getBodyUniqueId(k)
            position, orientation = c.getBasePositionAndOrientation(body)
            linear, angular = c.getBaseVelocity(body)
            values += [*position, *orientation, *linear, *angular]
            joints = c.getNumJoints(body)
            if joints:
                values += [v for state in c.getJointStates(body, range(joints)) for v in state[:2]]
        return all(math.isfinite(v) for v in values)

    def close(self) -> None:
        try:
            self.client.disconnect()
        except p.error:  # already disconnected
            pass

    # ---- small helpers used by several modules ----

    def link_frame(self, body: int, link: int) -> tuple[np.ndarray, np.ndarray]:
        """World position (3,) metres and quaternion (4,) xyzw of a link frame (-1: base)."""
        if link < 0:
            pos, quat = self.client.getBasePositionAndOrientation(body)
        else:
            state = self.client.getLinkState(body, link, computeForwardKinematics=1)
            pos, quat = state[4], state[5]
        return np.asarray(pos, dtype=float), np.asarray(quat, dtype=float)

    def link_velocity(self, body: int, link: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(centre of mass (3,) m, linear velocity (3,) m/s, angular velocity (3,) rad/s) of a link."""
        if link < 0:
            com, _ = self.client.getBasePositionAndOrientation(body)
            lin, ang = self.client.getBaseVelocity(body)
        else:
            state = self.client.getLinkState(body, link, computeLinkVelocity=1, computeForwardKinematics=1)
            com, lin, ang = state[0], state[6], state[7]
        return np.asarray(com, dtype=float), np.asarray(lin, dtype=float), np.asarray(ang, dtype=float)


def quat_from_rpy_deg(rpy_deg: Vec3) -> Quat:
    """Quaternion (x, y, z, w) of roll, pitch, yaw in degrees (extrinsic x-y-z, as the kit and PyBullet use)."""
    q = p.getQuaternionFromEuler([math.radians(a) for a in rpy_deg])
    return (float(q[0]), float(q[1]), float(q[2]), float(q[3]))


def rotation_matrix(quat: np.ndarray | Quat) -> np.ndarray:
    """3x3 rotation matrix of a quaternion (x, y, z, w)."""
    return np.asarray(p.getMatrixFromQuaternion(list(quat)), dtype=float).reshape(3, 3)
