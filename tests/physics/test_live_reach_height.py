"""The live drummer's size reaches its plans: the physics node's --height-m is the planner's height (a note beyond a
small drummer's reach is flagged, as ``batteur render --height`` flags it), and a plan with a knot beyond the body's
reach is played with those knots brought within it, the far note missed, instead of refused whole."""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np

from common.gesture.plan import GesturePlan, IssueReason
from common.kit import EventType, Limb, load_kit
from common.messages.score import LiveNote, ScoreLoad, ScoreTransport
from services.physics.core import PhysicsCore
from services.physics.node import LivePhysicsCore
from tests.far_kits import china_at

SCORE = "tempo 120\nmeter 4/4\nSN |x.x.x.x.|\nCH |....x...|\n"
"""A bar of four snare notes and a china note with the third."""
SENDER = "127.0.0.1:9"
CHINA_PITCH = 52


EDGE_KIT = china_at(load_kit("default"), 1.10)
"""The china within the default drummer's reach (1.15 m), beyond a 1.40 m drummer's (planner 1.02 m; physics: 1.41 m
from the right arm's root, reach 1.26 m)."""


def _unreachable(plan: GesturePlan) -> list[EventType | None]:
    return [i.event for i in plan.issues if i.reason == IssueReason.UNREACHABLE]


def _loaded(core: PhysicsCore, tmp_path: Path) -> None:
    (tmp_path / "china.txt").write_text(SCORE)
    core.score_player.library = [tmp_path]
    assert core.handle(ScoreLoad(path="china.txt"), 0.0, SENDER) == []


def test_the_live_planner_plans_for_the_nodes_height(tmp_path: Path) -> None:
    for height_m, flagged in ((1.4, [EventType.CHINA]), (1.75, [])):
        core = PhysicsCore(scene="drummer", kit=EDGE_KIT, height_m=height_m, grip="german", pose_rate_hz=0)
        try:
            _loaded(core, tmp_path)
            player = core.score_player
            assert player.score is not None
            planner = player._planner(list(player.score.events), player.score.beats, 1.0)
            plan = pickle.loads(pickle.dumps(planner))()  # as a planning process gets it
            assert _unreachable(plan) == flagged, f"a {height_m} m node"
        finally:
            core.close()


def test_a_plan_beyond_a_small_drummers_reach_plays_with_the_far_note_missed(tmp_path: Path) -> None:
    core = PhysicsCore(scene="drummer", kit=EDGE_KIT, height_m=1.4, grip="german", pose_rate_hz=0)
    try:
        _loaded(core, tmp_path)
        player = core.score_player
        assert core.handle(ScoreTransport(action="play", time=1.0, position=0.0), 0.0, SENDER) == []
        assert core.rejected_total == 0 and player.state == "playing"  # was: physics refused the whole plan
        assert player.last_plan is not None and _unreachable(player.last_plan) == [EventType.CHINA]
        assert player.status()["pulled_into_reach"] == {}  # the planner no longer sends the hand there
        assert [s.event for s in player.last_plan.strokes] == [EventType.SNARE] * 4  # the rest plays
        root, reach = core.scene.reach["right_hand"]
        knots = player.last_plan.trajectories[Limb.RIGHT_HAND].positions  # the plan the tracks hold
        assert np.linalg.norm(knots - root, axis=1).max() <= reach and len(core.scene.limb_tracks["right_hand"])
        # a live china note is spliced into the performance too, not refused: flagged, no knot beyond reach
        assert core.handle(LiveNote(time=3.25, pitch=CHINA_PITCH, velocity=100, channel=10), 1.5, SENDER) == []
        assert core.rejected_total == 0 and player.plans == 2
        assert EventType.CHINA in _unreachable(player.last_plan) and player.status()["pulled_into_reach"] == {}
    finally:
        core.close()


def test_the_live_node_plays_such_a_plan_planned_in_its_worker(tmp_path: Path) -> None:
    core = LivePhysicsCore(scene="drummer", kit=EDGE_KIT, height_m=1.4, grip="german", pose_rate_hz=0, mode="live",
                           planner="process")
    try:
        assert core.score_player.wait_loaded(120.0)  # as the node before it listens (play: refused meanwhile)
        _loaded(core, tmp_path)
        player = core.score_player
        assert core.handle(ScoreTransport(action="play", time=2.0, position=0.0), 0.0, SENDER) == []
        assert player.wait(60.0)
        core.step(core.time + 0.001)  # splices the plan that is ready
        assert core.rejected_total == 0 and player.plans == 1 and player.state == "playing"
        assert player.last_plan is not None and _unreachable(player.last_plan) == [EventType.CHINA]
        assert player.status()["pulled_into_reach"] == {}  # the planner no longer sends the hand there
        assert [s.event for s in player.last_plan.strokes] == [EventType.SNARE] * 4
    finally:
        core.close()
