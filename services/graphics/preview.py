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

:func:`score_preview` does the whole chain for a score file (what
``batteur graphics --preview-score SCORE`` shows): read (MIDI or text score,
``common.score``), distribute over the limbs, plan (``keyframe``: the 2001
paper's strokes shaped by the pose editor's saved UP/DOWN poses when given;
``gestures``: the gesture planner) and pose the figure.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from common.gesture.plan import GesturePlan, PlannedStroke
from common.kit import Kit, Limb
from common.messages import Impact
from common.score.events import Score, ScoreError
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


Progress = Callable[[int, int], None]
"""Called with (poses done, poses in all) while a preview is posed (the long part: the figure's IK)."""


def plan_preview(plan: GesturePlan, rate_hz: float = 60.0,
                 on_progress: Progress | None = None) -> tuple[PoseSequence, list[Impact]]:
    """The figure's pose sequence (``rate_hz``) and the impacts of ``plan``'s strokes.

    ``on_progress(done, total)`` is called after every pose.

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
        if on_progress is not None:
            on_progress(k + 1, count)
    impacts = [
        Impact(seq=i, time=s.time, instrument=s.object_id, zone=s.zone, r=min(max(s.r, 0.0), 2.0),
               theta=min(max(s.theta, -7.0), 7.0), velocity=min(max(s.velocity, 0.0), 100.0),
               impulse=0.0, peak_force=0.0, duration=min(max(s.contact_duration, 0.0), 1.0),
               part=f"{s.limb.value.split('_')[0]}_{'stick_tip' if 'hand' in s.limb.value else 'toe'}")
        for i, s in enumerate(sorted(plan.strokes, key=lambda s: s.time))
    ]
    return PoseSequence(list(LINK_NAMES), times, np.stack(frames)), impacts


Planner = Literal["keyframe", "gestures"]
PLANNERS: tuple[Planner, ...] = ("keyframe", "gestures")
"""``keyframe``: the 2001 paper's key-frame strokes (``plan_keyframes``); ``gestures``: ``plan_gestures``."""


@dataclass
class ScorePreview:
    """A score planned and posed for the view: what ``GraphicsCore.load_preview`` takes, and where it came from."""

    sequence: PoseSequence
    impacts: list[Impact]
    plan: GesturePlan
    score: Score
    poses: Path | None
    """The poses file the keyframe plan read (None: the built-in strokes)."""

    def summary(self) -> str:
        """One line for the log: notes, duration (seconds), planner, poses."""
        shaped = f", UP/DOWN poses from {self.poses}" if self.poses is not None else ""
        issues = f", {len(self.plan.issues)} feasibility issues" if self.plan.issues else ""
        return (f"{self.score.source or 'score'}: {len(self.impacts)} strokes over "
                f"{self.sequence.duration:.1f} s ({self.plan.mode} planner{shaped}{issues})")


def score_preview(path: str | Path, kit: Kit, planner: Planner = "keyframe", poses: str | Path | None = None,
                  rate_hz: float = 60.0, on_progress: Progress | None = None) -> ScorePreview:
    """Read, distribute, plan and pose a score file for the kinematic preview (no physics).

    Parameters
    ----------
    path : str | Path
        A MIDI file (``.mid``, ``.midi``, ``.smf``) or a Batteur text score (docs/score-format.md).
    kit : Kit
        The kit played (hit points, limbs); the view's kit.
    planner : {"keyframe", "gestures"}
        ``keyframe``: the 2001 paper's strokes; ``gestures``: the gesture planner (grip and nuance of a
        text score's ``grip``/``nuance`` directives).
    poses : str | Path | None
        ``keyframe`` only: the pose editor's ``poses.yaml``; a missing file (or None) means the built-in
        strokes (the tip raised along the surface normal).
    rate_hz : float
        Pose rate of the sequence, Hz.
    on_progress : callable(done, total), optional
        Called after every pose of the sequence (posing a long score takes seconds).

    Returns
    -------
    ScorePreview
        ``sequence`` (poses from the plan's start, 1 s before the first note, to its end, 1 s after the
        last, on the score's clock: the first note at its score time), ``impacts`` (one per planned stroke).

    Raises
    ------
    ScoreError
        (a ``ValueError``) naming the file: missing, unreadable or invalid score, a score with no drum
        event the kit plays, an invalid poses file, an unknown planner.
    """
    from common.gesture.keyframe import plan_keyframes
    from common.gesture.keyposes import KeyPoses
    from common.gesture.planner import PlannerConfig, plan_gestures
    from common.score.limbs import distribute
    from common.score.text import read_score

    if planner not in PLANNERS:
        raise ScoreError(f"unknown preview planner {planner!r} (one of: {', '.join(PLANNERS)})")
    if not math.isfinite(rate_hz) or rate_hz <= 0:
        raise ScoreError(f"preview pose rate must be positive, got {rate_hz}")
    score = read_score(path)
    if not score.events:
        why = "; ".join(score.warnings[-2:]) if score.warnings else "empty"
        raise ScoreError(f"{path}: no drum events to preview ({why})")
    assignment = distribute(score, kit)
    if not assignment.notes:
        raise ScoreError(f"{path}: none of the score's {len(score.events)} events can be played on kit "
                         f"{kit.name!r}")
    used: Path | None = None
    if planner == "keyframe":
        poses_path = Path(poses) if poses is not None else None
        try:
            keys = KeyPoses.load(poses_path)
        except OSError as exc:
            raise ScoreError(f"{poses_path}: cannot read the poses file ({exc.strerror or exc})") from None
        except ValueError as exc:
            raise ScoreError(str(exc)) from None
        used = poses_path if keys.poses else None
        plan = plan_keyframes(assignment, kit, score, poses=keys)
    else:
        default = PlannerConfig()
        config = PlannerConfig(grip=getattr(score, "grip", None) or default.grip,
                               nuance=getattr(score, "nuance", None) or default.nuance)
        plan = plan_gestures(assignment, kit, score, config)
    sequence, impacts = plan_preview(plan, rate_hz=rate_hz, on_progress=on_progress)
    return ScorePreview(sequence, impacts, plan, score, used)
