"""Bounded target queues: a track, a plan, the strike schedule and live notes refuse input past their bound.

A remote sender (OSC over UDP) can stream targets or live notes without end and a score's plan is queued whole:
past the bound the knot, message or plan is refused with a TargetError naming the limit, counted like every
other refusal (``PhysicsCore.rejected``, the node's Health ``dropped_other``), and nothing already queued is lost.
The bound itself fits a 24 h plan as dense as the densest Groove file's (docs/physics.md).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from common.gesture.plan import GesturePlan, LimbTrajectory
from common.gesture.planner import PlannerConfig, plan_gestures
from common.kit import EventType, Limb, load_kit
from common.messages.physics import CartesianTarget, JointTarget, PhysicsPosture, PhysicsReset, PhysicsStrike
from common.messages.score import LiveNote, ScoreTransport
from common.runtime import core_count
from common.score.events import MAX_SCORE_NOTES, MAX_SCORE_SECONDS, DrumEvent, Score
from common.score.hands import HandAlgorithm, Sticking
from common.score.limbs import distribute
from common.score.text import read_score
from services.physics import core as core_module
from services.physics import score_player as player_module
from services.physics.core import PhysicsCore
from services.physics.drummer import DrummerScene
from services.physics.splice import splice_plan
from services.physics.targets import MAX_TRACK_KNOTS, TargetError, Track

DENSE_GROOVE = Path(__file__).parents[1] / "data" / "groove_drummer1_s2_1_latin-chacarera_157_beat_3-4.mid"
"""148 s, 1,336 notes: 188 knots per second of music on the right hand, the densest of the shipped test files."""


def _knots(track: Track) -> tuple[list[float], list[list[float]], list[list[float]]]:
    """A track's knots as plain lists (times s, values, velocities), to compare before and after."""
    return list(track.times), [v.tolist() for v in track.values], [d.tolist() for d in track.velocities]


# ---------------------------------------------------------------------- Track alone


def _full_track(n: int = 4) -> Track:
    track = Track(3, max_knots=n)
    for k in range(n):
        track.add(0.1 * (k + 1), np.full(3, float(k)), np.full(3, -float(k)))
    return track


def test_a_track_refuses_the_knot_past_its_bound_and_keeps_the_others() -> None:
    track = _full_track()
    before = _knots(track)
    with pytest.raises(TargetError, match=r"4 knots per track \(MAX_TRACK_KNOTS\)"):
        track.add(0.5, np.ones(3), np.zeros(3))
    assert _knots(track) == before
    assert track.sample(0.4)[0].tolist() == [3.0, 3.0, 3.0]  # the last knot still holds


def test_replacing_the_tail_still_works_at_the_bound() -> None:
    """A re-planned knot at or before the last one replaces the tail from there: it never adds to a full track."""
    track = _full_track()
    track.add(0.4, np.full(3, 9.0), np.zeros(3))  # the last knot, re-planned
    assert track.times == pytest.approx([0.1, 0.2, 0.3, 0.4]) and track.values[-1].tolist() == [9.0] * 3
    track.add(0.25, np.full(3, 7.0), np.zeros(3))  # replaces 0.3 and 0.4
    assert track.times == pytest.approx([0.1, 0.2, 0.25])
    track.extend(np.array([0.2, 0.3, 0.4]), np.zeros((3, 3)), np.zeros((3, 3)))  # replaces from 0.2: 4 knots
    assert track.times == pytest.approx([0.1, 0.2, 0.3, 0.4])


@pytest.mark.parametrize("bad", ["too_many", "nan"])
def test_a_refused_extend_queues_nothing(bad: str) -> None:
    """Many knots at once are checked before the first is queued: a refusal keeps the track as it was."""
    track = _full_track()
    times = np.array([0.35, 0.45, 0.55])  # would replace 0.4 and leave 6 knots
    values = np.zeros((3, 3))
    if bad == "nan":
        track.max_knots = 10
        values[2, 1] = np.nan
    before = _knots(track)
    with pytest.raises(TargetError, match="MAX_TRACK_KNOTS" if bad == "too_many" else "finite"):
        track.extend(times, values, np.zeros((3, 3)))
    assert _knots(track) == before


def _knots_per_second(score: Score) -> float:
    """The most knots per second of music (first to last note) the default planner gives one limb of ``score``."""
    kit = load_kit("default")
    plan = plan_gestures(distribute(score, kit, HandAlgorithm.VITERBI, Sticking.NONE), kit, score, PlannerConfig())
    t0, t1 = score.events[0].time, score.events[-1].time
    return max(int(np.count_nonzero((traj.times >= t0) & (traj.times <= t1))) / (t1 - t0)
               for traj in plan.trajectories.values())


def test_the_bound_fits_a_24_hour_plan_as_dense_as_a_dense_groove() -> None:
    """The longest score the reader accepts (24 h) planned as densely as a dense Groove beat, or with its most notes
    (500,000) all on one hand, evenly spread, still fits the default bound with a quarter to spare."""
    assert Track(3).max_knots == MAX_TRACK_KNOTS
    groove = _knots_per_second(read_score(DENSE_GROOVE))
    assert groove > 150  # a dense plan: else the check below proves little
    assert groove * MAX_SCORE_SECONDS * 1.25 <= MAX_TRACK_KNOTS
    rate = MAX_SCORE_NOTES / MAX_SCORE_SECONDS  # notes per second
    roll = [DrumEvent(time=1.0 + k / rate, event=EventType.SNARE, velocity=0.8, pitch=38) for k in range(60)]
    evenly = _knots_per_second(Score(events=roll, beats=np.zeros(0), source="test"))
    assert evenly * MAX_SCORE_SECONDS * 1.25 <= MAX_TRACK_KNOTS


# ---------------------------------------------------------------------- the drummer core


@pytest.fixture
def core(drummer: PhysicsCore, monkeypatch: pytest.MonkeyPatch) -> PhysicsCore:
    """The shared drummer core, reset, its refusals forgotten, every limb track bounded at 40 knots."""
    drummer.handle(PhysicsReset(time=0.0), 0.0, "test")
    drummer.rejected.clear()
    drummer.score_player.errors.clear()
    scene = _scene(drummer)
    for track in scene.limb_tracks.values():
        monkeypatch.setattr(track, "max_knots", 40)
    return drummer


def _scene(core: PhysicsCore) -> DrummerScene:
    assert isinstance(core.scene, DrummerScene)
    return core.scene


def _tracks(scene: DrummerScene) -> dict[str, tuple[list[float], list[list[float]], list[list[float]]]]:
    return {limb: _knots(track) for limb, track in scene.limb_tracks.items()}


def _target(scene: DrummerScene, time: float, limb: str = "right_hand") -> CartesianTarget:
    x, y, z = (float(c) for c in scene.rest_targets[limb])
    return CartesianTarget(limb=limb, time=time, x=x, y=y, z=z + 0.01 * time, vx=0.0, vy=0.0, vz=0.0)


def test_a_streamed_target_past_the_bound_is_refused_and_counted(core: PhysicsCore) -> None:
    scene = _scene(core)
    for k in range(40):
        core.handle(_target(scene, 0.1 + 0.01 * k), 0.0, "test")
    before = _tracks(scene)
    core.handle(_target(scene, 0.6), 0.0, "test")
    assert core.rejected == {"CartesianTarget": 1}
    assert core_count(core, "rejected_total") == 1  # what the node's Health adds to dropped_other
    assert _tracks(scene) == before
    core.handle(_target(scene, 0.49), 0.0, "test")  # the last knot re-planned: accepted at the bound
    assert core.rejected_total == 1 and scene.limb_tracks["right_hand"].times[-1] == pytest.approx(0.49)


def test_a_joint_target_past_the_bound_is_refused_and_counted(core: PhysicsCore,
                                                              monkeypatch: pytest.MonkeyPatch) -> None:
    scene = _scene(core)
    monkeypatch.setattr(scene.joint_track, "max_knots", 2)
    values = (*scene.rest.tolist(), *[0.0] * len(scene.rest))
    for time in (0.1, 0.2, 0.3):
        core.handle(JointTarget(time=time, values=values), 0.0, "test")
    assert core.rejected == {"JointTarget": 1} and scene.joint_track.times == pytest.approx([0.1, 0.2])
    scene.joint_track.clear()


def _plan(scene: DrummerScene, knots: dict[str, int], start: float = 0.5) -> GesturePlan:
    """A plan of ``knots[limb]`` knots per limb, 10 ms apart from ``start`` seconds, at the limb's rest target."""
    trajectories = {}
    for name, n in knots.items():
        rest = scene.rest_targets[name]
        times = start + 0.01 * np.arange(n)
        positions = np.repeat(rest[None, :], n, axis=0)
        trajectories[Limb(name)] = LimbTrajectory(Limb(name), times, positions, np.zeros((n, 3)))
    end = start + 0.01 * (max(knots.values()) - 1)
    return GesturePlan(trajectories=trajectories, strokes=[], start_time=start, end_time=end)


def test_a_spliced_plan_past_the_bound_is_refused_whole_and_keeps_the_queued_targets(core: PhysicsCore) -> None:
    """The right hand's plan fits but the left hand's does not: neither limb may change (before, the right hand
    was spliced first); the plan that fills the track exactly is queued."""
    scene = _scene(core)
    for k in range(5):
        core.handle(_target(scene, 0.1 + 0.1 * k, "left_hand"), 0.0, "test")
        core.handle(_target(scene, 0.1 + 0.1 * k, "right_hand"), 0.0, "test")
    before = _tracks(scene)
    # the plan starts 0.1 s after the splice at 0.25 s: too soon to brake first, so no bridge knot
    with pytest.raises(TargetError, match="MAX_TRACK_KNOTS"):
        splice_plan(scene, _plan(scene, {"right_hand": 10, "left_hand": 38}, start=0.35), 0.25)
    assert _tracks(scene) == before
    splice_plan(scene, _plan(scene, {"right_hand": 10, "left_hand": 37}, start=0.35), 0.25)
    assert len(scene.limb_tracks["left_hand"]) == 40  # 0.1, 0.2, the splice at 0.25 and 37 knots of the plan
    assert len(scene.limb_tracks["right_hand"]) == 13


def test_a_loaded_plan_past_the_bound_is_refused_and_keeps_the_queued_targets(core: PhysicsCore) -> None:
    scene = _scene(core)
    core.handle(_target(scene, 0.2, "left_hand"), 0.0, "test")
    before = _tracks(scene)
    with pytest.raises(TargetError, match="MAX_TRACK_KNOTS"):
        core.load_plan(_plan(scene, {"left_hand": 39}), start_at=0.5)  # + the 2 lead-in knots: 41
    assert _tracks(scene) == before
    core.load_plan(_plan(scene, {"left_hand": 38}), start_at=0.5)
    assert len(scene.limb_tracks["left_hand"]) <= 40


def test_a_stop_that_would_overfill_a_track_is_refused_and_changes_nothing(core: PhysicsCore) -> None:
    scene = _scene(core)
    core.handle(_target(scene, 0.2, "left_hand"), 0.0, "test")  # braked first (the tracks go in limb order)
    for k in range(40):
        core.handle(_target(scene, 0.01 * k, "right_hand"), 0.0, "test")
    before = _tracks(scene)
    core.handle(ScoreTransport(action="stop", time=1.0, position=0.0), 0.0, "test")  # 3 more knots after 0.39
    assert core.rejected == {"ScoreTransport": 1}
    assert _tracks(scene) == before


def test_live_notes_past_a_performances_bound_are_refused_and_counted(core: PhysicsCore,
                                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """A performance holds at most as many notes as a score may (MAX_SCORE_NOTES; 3 here): a sender streaming
    notes far ahead is refused past it, and the notes already accepted stay."""
    monkeypatch.setattr(player_module, "MAX_PERFORMANCE_NOTES", 3)
    scene = _scene(core)
    for track in scene.limb_tracks.values():
        monkeypatch.setattr(track, "max_knots", MAX_TRACK_KNOTS)
    for k in range(4):
        core.handle(LiveNote(time=1.0 + 0.5 * k, pitch=38, velocity=100, channel=10), 0.0, "test")
    player = core.score_player
    assert core.rejected == {"LiveNote": 1}
    assert [e.time for e in player.events] == pytest.approx([1.0, 1.5, 2.0])


def test_unknown_live_pitches_are_counted_without_keeping_each(core: PhysicsCore) -> None:
    player = core.score_player
    start = player.status()["unknown_live_pitches"]
    assert isinstance(start, int)
    for k in range(300):
        core.handle(LiveNote(time=1.0 + 0.02 * k, pitch=127, velocity=100, channel=10), 0.0, "test")
    assert player.status()["unknown_live_pitches"] == start + 300
    assert len(player.live.unknown) <= player_module.UNKNOWN_PITCHES_KEPT
    assert player.live.unknown[-1].time == pytest.approx(1.0 + 0.02 * 299)  # the latest are kept


# ---------------------------------------------------------------------- the strike scene


def test_strikes_past_the_schedules_bound_are_refused_and_counted(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(core_module, "MAX_PENDING_STRIKES", 2)
    core = PhysicsCore(scene="strike", pose_rate_hz=0)
    try:
        for time in (0.3, 0.2, 0.4):
            core.handle(PhysicsStrike(time=time, velocity=3.0), 0.0, "test")
        assert core.rejected == {"PhysicsStrike": 1}
        with pytest.raises(TargetError, match="MAX_PENDING_STRIKES"):
            core.schedule_strikes([(0.5, 2.0)])
        assert [s.time for s in core.scene.pending] == pytest.approx([0.2, 0.3])  # type: ignore[attr-defined]
    finally:
        core.close()


def test_a_posture_glide_that_would_be_cut_in_half_is_refused_whole(core: PhysicsCore,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    scene = _scene(core)
    monkeypatch.setattr(scene.joint_track, "max_knots", 3)
    values = (*scene.rest.tolist(), *[0.0] * len(scene.rest))
    for time in (0.1, 0.2):
        core.handle(JointTarget(time=time, values=values), 0.0, "test")
    bent = [float(v) + 0.05 for v in scene.rest]
    # a glide is two knots (from here, to the posture): one slot left, so neither is queued
    core.handle(PhysicsPosture(time=0.5, duration=0.3, values=bent), 0.0, "test")
    assert core.rejected == {"PhysicsPosture": 1} and scene.joint_track.times == pytest.approx([0.1, 0.2])
    core.handle(PhysicsPosture(time=0.5, duration=0.0, values=bent), 0.0, "test")  # a jump is one knot: it fits
    assert core.rejected == {"PhysicsPosture": 1} and scene.joint_track.times == pytest.approx([0.1, 0.2, 0.5])
    scene.joint_track.clear()
