"""Simple test strokes for the drummer (tests and benchmarks; the real gestures come from common/gesture).

A stroke drives an effector from a rest point above a surface down onto a
hit point, arriving at ``velocity`` m/s along ``-normal`` at ``time``, then
back up (rebound at ``rebound`` times the speed) to the rest point: knots
(times, positions, velocities) for :class:`~services.physics.targets.Track`
or a :class:`~common.gesture.plan.LimbTrajectory`. """

from __future__ import annotations

import numpy as np


def stroke_knots(rest: np.ndarray, hit: np.ndarray, normal: np.ndarray, time: float, velocity: float,
                 lift_s: float = 0.12, return_s: float = 0.15, rebound: float = 0.5,
                 contact_s: float = 0.004) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Knots of one stroke: times (N,) s, positions (N, 3) m, velocities (N, 3) m/s.

    Down from ``rest`` to ``hit`` arriving at ``velocity`` along ``-normal`` at ``time``; the velocity
    reverses over ``contact_s`` to ``rebound * velocity`` along ``+normal`` (as the gesture planner's
    strokes do), then back to ``rest`` at ``time + return_s``.
    """
    n = np.asarray(normal, dtype=float)
    n = n / np.linalg.norm(n)
    rest = np.asarray(rest, dtype=float)
    contact = np.asarray(hit, dtype=float)
    times = np.array([time - lift_s, time, time + contact_s, time + return_s])
    positions = np.array([rest, contact, contact, rest])
    velocities = np.array([np.zeros(3), -n * velocity, n * rebound * velocity, np.zeros(3)])
    return times, positions, velocities


def strokes_knots(rest: np.ndarray, hit: np.ndarray, normal: np.ndarray, times: list[float],
                  velocities: list[float], lift_s: float = 0.12, return_s: float = 0.15, rebound: float = 0.5,
                  contact_s: float = 0.004) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Several strokes of one effector, merged into one knot sequence (strokes must not overlap)."""
    ts: list[float] = []
    ps: list[np.ndarray] = []
    vs: list[np.ndarray] = []
    for t, v in zip(times, velocities, strict=True):
        kt, kp, kv = stroke_knots(rest, hit, normal, t, v, lift_s, return_s, rebound, contact_s)
        for k in range(len(kt)):
            if ts and kt[k] <= ts[-1] + 1e-6:
                continue
            ts.append(float(kt[k]))
            ps.append(kp[k])
            vs.append(kv[k])
    return np.array(ts), np.array(ps), np.array(vs)
