"""Kinematic preview of a score: the stick figure follows a gesture plan, no physics.

``common.gesture`` turns a score into a :class:`~common.gesture.plan.GesturePlan`
(the 2001 paper's keyframe strokes with ``plan_keyframes``, or the gesture
database's): per limb a trajectory of the effector (stick tip, ball of the
foot) and the planned contacts. :func:`plan_preview` poses the graphics
figure so that its effectors follow those trajectories (two-bone IK, the
stick tilting with the tip's height above the surface of the nearest stroke)
and turns every planned contact into an :class:`~common.messages.Impact`, so
the view (``GraphicsCore.load_preview``), the video and the exports can show
a score before, or without, the physics run.
"""

from __future__ import annotations

import math

import numpy as np

from common.gesture.plan import GesturePlan, PlannedStroke
from common.kit import Limb
from common.messages import Impact
from services.graphics.figure import LINK_NAMES, LimbGoal, figure_pose
from services.graphics.sequence import PoseSequence

UP = np.array([0.0, 0.0, 1.0])


def _nearest(strokes: list[PlannedStroke], times: np.ndarray, t: float) -> PlannedStroke | None:
    if not strokes:
        return None
    j = int(np.searchsorted(times, t))
    candidates = [strokes[k] for k in (j - 1, j) if 0 <= k < len(strokes)]
    return min(candidates, key=lambda s: abs(s.time - t))


def _goal(limb: Limb, position: np.ndarray, stroke: PlannedStroke | None) -> LimbGoal:
    hand = limb in (Limb.LEFT_HAND, Limb.RIGHT_HAND)
    if stroke is None:
        return LimbGoal(position - UP * (0.1 if hand else 0.0), UP, 0.1 if hand else 0.0)
    normal = np.asarray(stroke.normal, float) if hand else UP
    normal = normal / max(float(np.linalg.norm(normal)), 1e-9)
    height = float(np.dot(position - np.asarray(stroke.target, float), normal))
    return LimbGoal(position - normal * height, normal, height)


def plan_preview(plan: GesturePlan, rate_hz: float = 60.0) -> tuple[PoseSequence, list[Impact]]:
    """The figure's pose sequence (``rate_hz``) and the impacts of ``plan``'s strokes.

    Returns
    -------
    sequence : PoseSequence
        Poses from ``plan.start_time`` to ``plan.end_time``, link names of :data:`LINK_NAMES`.
    impacts : list of Impact
        One per planned stroke, at its contact time.
    """
    start, end = plan.start_time, max(plan.end_time, plan.start_time)
    count = int(math.floor((end - start) * rate_hz + 1e-9)) + 1
    times = start + np.arange(count) / rate_hz
    by_limb = {limb: plan.strokes_of(limb) for limb in plan.trajectories}
    stroke_times = {limb: np.array([s.time for s in strokes]) for limb, strokes in by_limb.items()}
    positions = {limb: traj.sample_many(times)[0] for limb, traj in plan.trajectories.items()}
    frames = []
    for k, t in enumerate(times):
        goals = {
            limb.value: _goal(limb, positions[limb][k], _nearest(by_limb[limb], stroke_times[limb], float(t)))
            for limb in plan.trajectories
        }
        nod = math.degrees(plan.head.sample(float(t))[1]) if plan.head is not None else 0.0
        frames.append(figure_pose(goals, nod_deg=nod))
    impacts = [
        Impact(seq=i, time=s.time, instrument=s.object_id, zone=s.zone, r=min(max(s.r, 0.0), 2.0),
               theta=min(max(s.theta, -7.0), 7.0), velocity=min(max(s.velocity, 0.0), 100.0),
               impulse=0.0, peak_force=0.0, duration=min(max(s.contact_duration, 0.0), 1.0),
               part=f"{s.limb.value.split('_')[0]}_{'stick_tip' if 'hand' in s.limb.value else 'toe'}")
        for i, s in enumerate(sorted(plan.strokes, key=lambda s: s.time))
    ]
    return PoseSequence(list(LINK_NAMES), times, np.stack(frames)), impacts
