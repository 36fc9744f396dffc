"""The live physics node built from a BVH skeleton (``--skeleton-bvh``) plans with that skeleton's arms and legs,
as ``batteur render --skeleton-bvh`` does: a short-armed skeleton's planner flags a china the 1.75 m drummer of the
table reaches, a long-armed 1.40 m one's does not flag a china the 1.40 m drummer of the table does not reach; the
node's kit load warning measures the skeleton's reach too."""

from __future__ import annotations

import argparse
import contextlib
import logging
import pickle
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from common.gesture.plan import IssueReason
from common.kit import EventType, load_kit, save_kit
from common.messages.score import ScoreLoad
from services.physics.core import PhysicsCore
from tests.far_kits import china_at
from tests.render.test_render_skeleton_reach import _skeleton

SCORE = "tempo 120\nmeter 4/4\nSN |x.x.x.x.|\nCH |....x...|\n"
"""A bar of four snare notes and a china note with the third."""
EDGE_KIT = china_at(load_kit("default"), 1.10)
"""The china 1.10 m from the default drummer's right shoulder: within the table's 1.75 m reach (1.15 m), beyond a
1.40 m drummer's (1.02 m)."""


@contextlib.contextmanager
def _china_planner(tmp_path: Path, height_m: float, skeleton: Path | None) -> Iterator[tuple[Any, Callable[[], Any]]]:
    """A drummer-scene core of that height (and skeleton) with :data:`SCORE` loaded: its score player and the
    planner of the score's events, as a planning process gets it."""
    core = PhysicsCore(scene="drummer", kit=EDGE_KIT, height_m=height_m, grip="german", pose_rate_hz=0,
                       skeleton_bvh=None if skeleton is None else str(skeleton))
    try:
        (tmp_path / "china.txt").write_text(SCORE)
        player = core.score_player
        player.library = [tmp_path]
        assert core.handle(ScoreLoad(path="china.txt"), 0.0, "127.0.0.1:9") == []
        assert player.score is not None
        yield player, player._planner(list(player.score.events), player.score.beats, 1.0)
    finally:
        core.close()


def _flagged(tmp_path: Path, height_m: float, skeleton: Path | None) -> list[EventType | None]:
    """The events the node's planner flags ``unreachable`` in :data:`SCORE`, planned as a planning process does."""
    with _china_planner(tmp_path, height_m, skeleton) as (_, planner):
        plan = pickle.loads(pickle.dumps(planner))()
    return [i.event for i in plan.issues if i.reason == IssueReason.UNREACHABLE]


def test_the_live_planner_plans_with_the_skeletons_reach(tmp_path: Path) -> None:
    short = _skeleton(tmp_path / "short.bvh", 20, 18, 25, 25)  # arm 0.47 m with the table's hand (the table: 0.64)
    assert _flagged(tmp_path, 1.75, short) == [EventType.CHINA]  # was: none, the height's reach
    long = _skeleton(tmp_path / "long.bvh", 36, 34, 42, 44)
    assert _flagged(tmp_path, 1.4, long) == []  # was: the china, as the 1.40 m drummer of the table


def test_the_nodes_kit_warning_measures_the_skeletons_reach(tmp_path: Path, caplog: pytest.LogCaptureFixture,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    from services.physics.node import PhysicsNodeSettings, make_core

    monkeypatch.delenv("BATTEUR_CONFIG", raising=False)
    kit = tmp_path / "edge.yaml"
    save_kit(EDGE_KIT, kit)
    short = _skeleton(tmp_path / "short.bvh", 20, 18, 25, 25)
    with caplog.at_level(logging.WARNING, logger="common.kit"):
        core = make_core(PhysicsNodeSettings(discovery=False, kit=str(kit), skeleton_bvh=str(short)),
                         argparse.Namespace())
        core.close()
    said = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING and r.name == "common.kit"]
    assert any("china: out of both hands' reach" in line and "a skeleton's hand reaching 0.977 m" in line
               for line in said)  # was: none (the table's 1.75 m drummer reaches it)


def test_knots_pulled_in_are_logged_against_the_skeletons_reach(tmp_path: Path,
                                                               caplog: pytest.LogCaptureFixture) -> None:
    """A plan's knots brought within a skeleton-built body's reach are logged as the skeleton's, not as the
    height's drummer (whose reach the body does not have)."""
    short = _skeleton(tmp_path / "short.bvh", 20, 18, 25, 25)
    with _china_planner(tmp_path, 1.75, short) as (player, planner), \
            caplog.at_level(logging.INFO, logger="batteur.physics.score"):
        player._account(planner(), pulled={"right_hand": 3})
    said = [r.getMessage() for r in caplog.records if "reach brought within" in r.getMessage()]
    assert said == ["plan: 3 right hand knots beyond the skeleton's reach brought within it: the notes there are "
                    "missed"]  # was: "the 1.75 m drummer's reach"
