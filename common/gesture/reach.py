"""Gesture plans brought within the drummer's reach (metres), for the render and the live physics node alike.

Physics refuses a whole plan for one knot beyond a limb's reach (services/physics/drummer.py ``check_cartesian``);
a kit that is too large for a small drummer would then play nothing. :func:`pull_into_reach` moves such knots just
inside the reach instead: the notes there are missed (the planner flags them ``unreachable``, for the same drummer:
common/score/limbs.py) and the rest plays.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np

from common.gesture.plan import GesturePlan

REACH_MARGIN = 0.999
"""A knot pulled into reach lands this share of the reach from the limb's root (physics refuses beyond it)."""

Reach = Mapping[str, tuple[np.ndarray, float]]
"""Limb name -> (its root, a world point in metres; its reach, metres): physics' ``DrummerScene.reach``."""


def pull_into_reach(plan: GesturePlan, reach: Reach) -> tuple[GesturePlan, dict[str, int]]:
    """``plan`` with each limb's knots farther than its reach from its root (``reach``: limb name -> (root,
    metres)) moved toward the root to just within it, and the knots moved per limb. Physics refuses a whole plan
    for one such knot; a drummer too small for the kit then misses those notes (the planner flags them
    ``unreachable``) and plays the rest. A plan within reach is returned as it is (the same arrays)."""
    trajectories = dict(plan.trajectories)
    counts: dict[str, int] = {}
    for limb, traj in plan.trajectories.items():
        name = str(getattr(limb, "value", limb))
        if name not in reach:
            continue  # physics names the limb it does not know
        root, length = reach[name]
        offsets = np.asarray(traj.positions, dtype=float) - root
        distances = np.linalg.norm(offsets, axis=1)
        far = distances > length  # NaN: left to physics' own refusal
        if not far.any():
            continue
        positions = np.array(traj.positions, dtype=float)
        positions[far] = root + offsets[far] * (REACH_MARGIN * length / distances[far])[:, None]
        trajectories[limb] = dataclasses.replace(traj, positions=positions)
        counts[name] = int(far.sum())
    if not counts:
        return plan, counts
    return dataclasses.replace(plan, trajectories=trajectories), counts
