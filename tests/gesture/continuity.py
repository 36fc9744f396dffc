"""Continuity of a gesture plan, for the planner's tests."""

from __future__ import annotations

import numpy as np

from common.gesture.plan import GesturePlan


def largest_jumps(plan: GesturePlan, eps: float = 1e-9) -> tuple[float, float]:
    """Largest jump (m, m/s) in position and velocity across every knot of every limb (left vs right limit)."""
    worst_p = worst_v = 0.0
    for traj in plan.trajectories.values():
        inner = traj.times[1:-1]
        p0, v0 = traj.sample_many(inner - eps)
        p1, v1 = traj.sample_many(inner + eps)
        worst_p = max(worst_p, float(np.abs(p1 - p0).max(initial=0.0)))
        worst_v = max(worst_v, float(np.abs(v1 - v0).max(initial=0.0)))
    return worst_p, worst_v
