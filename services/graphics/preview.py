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

:class:`PreviewClock` is where the looping preview is at a wall (rig) time, at a playback rate over the planned
motion (``--preview-rate``, the page's rate select) that may change while it plays.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from common.gesture.plan import GesturePlan, PlannedStroke
from common.kit import Kit, Limb
from common.messages import Impact
from common.messages.graphics import PREVIEW_MAX_RATE, PREVIEW_MIN_RATE
from common.score.events import Score, ScoreError
from services.graphics.figure import LINK_NAMES, LimbGoal, figure_pose
from services.graphics.sequence import PoseSequence

UP = np.array([0.0, 0.0, 1.0])

PREVIEW_RATES: tuple[float, ...] = (0.25, 0.5, 0.75, 1.0, 1.25, 1.5, 2.0)
"""The playback rates the page offers (motion seconds per wall second)."""
MIN_RATE, MAX_RATE = PREVIEW_MIN_RATE, PREVIEW_MAX_RATE
"""The playback rates a preview accepts (``--preview-rate``, the page, ``/batteur/graphics/preview_rate``)."""
LOOP_PAUSE_S = 0.5
"""Motion seconds between the end of a preview and its start again (scaled by the rate like the motion)."""


def check_rate(rate: object) -> float:
    """``rate`` as a float, or ``ValueError`` saying what a preview rate is."""
    if isinstance(rate, bool) or not isinstance(rate, (int, float)) or not math.isfinite(rate) \
            or not MIN_RATE <= rate <= MAX_RATE:
        raise ValueError(f"preview rate {rate!r}: a number from {MIN_RATE:g} to {MAX_RATE:g} "
                         "(1: as planned, 0.5: half speed)")
    return float(rate)


class PreviewClock:
    """Where a looping preview is at wall (rig) time ``now``: its motion plays ``rate`` seconds per wall second.

    The preview runs from motion time ``start`` for ``span`` seconds, then :data:`LOOP_PAUSE_S`, then again. A rate
    changed while it plays takes effect from that instant: the motion goes on from where it is (no jump), faster or
    slower. Wall times are the node's rig clock, seconds.
    """

    def __init__(self, start: float, span: float, now: float | None = None, rate: float = 1.0,
                 pause: float = LOOP_PAUSE_S) -> None:
        self.start = float(start)
        self.span = max(float(span), 1e-6)
        self.pause = max(float(pause), 0.0)
        """Motion seconds between a lap's end and the next lap's start (0: a bar loop, seamless)."""
        self.rate = check_rate(rate)
        self._anchor = None if now is None else float(now)
        """Wall time at which the motion had played :attr:`_played` seconds (from its first start); None: the first
        wall time asked about (a preview loaded before the node's clock runs starts when it is first shown, not at
        rig time 0: a viewer started an hour into a rig began mid-bar at lap 424)."""
        self._played = 0.0

    @property
    def period(self) -> float:
        """Motion seconds of one lap (the preview and the pause after it)."""
        return self.span + self.pause

    def played(self, now: float) -> float:
        """Motion seconds played since the first start, laps included."""
        if self._anchor is None:
            self._anchor = float(now)
        return self._played + (now - self._anchor) * self.rate

    def position(self, now: float) -> float:
        """The motion time shown at wall time ``now`` (on the sequence's clock: ``start`` at each lap's start)."""
        return self.start + self.played(now) % self.period

    def lap(self, now: float) -> int:
        """Laps completed at wall time ``now`` (0 during the first)."""
        return int(self.played(now) // self.period)

    def set_rate(self, rate: float, now: float) -> None:
        """Play at ``rate`` from wall time ``now`` on, from the motion time shown then; ``ValueError`` out of range."""
        rate = check_rate(rate)
        self._played, self._anchor = self.played(now), float(now)
        self.rate = rate

    def set_span(self, start: float, span: float, pause: float, now: float) -> None:
        """Loop ``span`` motion seconds from ``start`` (then ``pause``) from wall time ``now`` on, at the same rate.

        The motion goes on from where it is when that is inside the new span (no jump), else from ``start``; the
        laps count from 0 again."""
        shown = self.position(now)
        self.start, self.span, self.pause = float(start), max(float(span), 1e-6), max(float(pause), 0.0)
        inside = self.start <= shown < self.start + self.span
        self._played, self._anchor = (shown - self.start if inside else 0.0), float(now)

    def shift(self, step_s: float) -> None:
        """The wall clock stepped by ``step_s`` seconds: the motion shown stays where it was."""
        if self._anchor is not None:
            self._anchor += step_s


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


def parse_bars(text: str) -> tuple[int, int]:
    """``"3"`` or ``"3-4"`` (bars from 1, as the status panel counts them) as (first, last); ``ValueError``."""
    first, sep, last = text.strip().partition("-")
    try:
        bars = (int(first), int(last) if sep else int(first))
    except ValueError:
        raise ValueError(f"--preview-bars {text!r}: a bar or a range of bars from 1, e.g. 3 or 3-4") from None
    if bars[0] < 1 or bars[1] < bars[0]:
        raise ValueError(f"--preview-bars {text!r}: bars count from 1 and the range must not end before it starts "
                         "(e.g. 3-4)")
    return bars


def _beat_seconds(beats: np.ndarray, position: float) -> float:
    """Score time (s) of ``position`` beats from the first beat (past the last, the last spacing goes on)."""
    k = min(max(int(math.floor(position)), 0), len(beats) - 2)
    return float(beats[k] + (position - k) * (beats[k + 1] - beats[k]))


def bar_span(score: Score, first: int, last: int) -> tuple[float, float]:
    """Score times (s) of the start of bar ``first`` and the end of bar ``last`` (bars from 1), the inverse of
    ``common.score.position.bar_beat`` (its bars: the score's ``bar_beats``, bars as long as the last past them,
    bars of 4 beats in a score without them); ``ValueError`` for a score without beats."""
    from common.score.position import DEFAULT_BEATS_PER_BAR

    beats = np.asarray(score.beats, float)
    if len(beats) < 2:
        raise ValueError("--preview-bars: the score has no beats to count bars by")
    starts = [float(b) for b in score.bar_beats]

    def bar_start(bar: int) -> float:  # beats from the first beat, bar from 0
        if not starts:
            return float(bar * DEFAULT_BEATS_PER_BAR)
        if bar < len(starts):
            return starts[bar]
        length = len(beats) - 1 - starts[-1]
        if length <= 0:
            length = starts[-1] - starts[-2] if len(starts) > 1 else float(DEFAULT_BEATS_PER_BAR)
        return starts[-1] + (bar - len(starts) + 1) * length

    return _beat_seconds(beats, bar_start(first - 1)), _beat_seconds(beats, bar_start(last))


def bar_loop(score: Score, impacts: list[Impact], end: float, first: int, last: int) -> tuple[float, float]:
    """The span (start, end), seconds on the score's clock, that looping bars ``first`` to ``last`` (from 1) of
    ``score`` plays: :func:`bar_span` cut at ``end`` (the preview's last pose). ``ValueError`` for a range that
    ends past the bar of the score's last note (``impacts``: the preview's strokes; "the score has 3 bars": cutting
    the range silently at the end would loop bars other than the ones asked for) or a score without beats."""
    from common.score.position import bar_beat

    start, stop = bar_span(score, first, last)
    name = Path(score.source).name if score.source else "score"
    if not impacts:
        raise ValueError(f"the score has no notes ({name})")
    last_note = max(i.time for i in impacts)
    where = bar_beat(score, last_note)
    if where is None:  # the last note before the first beat: no bar holds a note
        if start > last_note:
            raise ValueError(f"the score's last note is before bar {first} ({name})")
    elif last > where.bar + 1:
        bars = where.bar + 1
        raise ValueError(f"the score has {bars} bar{'' if bars == 1 else 's'} ({name})")
    return start, min(stop, float(end))


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
                  rate_hz: float = 60.0, on_progress: Progress | None = None,
                  midi: Mapping[str, Any] | None = None) -> ScorePreview:
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
    midi : mapping, optional
        How a MIDI file is read: :func:`common.score.midi.read_midi`'s keyword arguments (the node's
        ``--drum-channels``, ``--drum-map``, ``--hihat-cc4``); a text score ignores them.

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
    score = read_score(path, kit=kit, **(midi or {}))  # ids and doubles: the previewed kit's objects
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
