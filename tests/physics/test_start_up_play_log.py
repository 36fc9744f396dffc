"""The physics node's own ``--play-at`` start, already past when its scene is ready, is said at INFO; a remote play
arriving late is still a warning.

Every default ``batteur rig --score demo`` start warned ``play at rig time 1.000 s asked at 4.411 s, already past``:
the rig's defaults put the score 4 s after launch, and physics (3 s to build its scene, 7-15 s under load) listens
later. A normal start should not warn; how late it is stays in the log.
"""

from __future__ import annotations

import logging
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

from common.kit import load_kit
from services.physics.core import PhysicsCore
from services.physics.node import PhysicsNodeSettings, start_score

SCORE = Path(__file__).parents[1] / "render" / "short_groove.txt"


def drummer() -> PhysicsCore:
    physics = PhysicsCore(scene="drummer", kit=load_kit("default"), grip="german", pose_rate_hz=0, mode="live")
    physics.score_player.load(SCORE, trusted=True)
    return physics


def late_lines(caplog: pytest.LogCaptureFixture) -> list[tuple[int, str]]:
    return [(r.levelno, r.getMessage()) for r in caplog.records
            if r.name == "batteur.physics.score" and ("already past" in r.getMessage()
                                                       or "too close to prepare" in r.getMessage())]


@pytest.mark.parametrize("play_at", [1.0, 4.5])  # long past; just after the node listens (too close to prepare)
def test_the_nodes_own_start_later_than_play_at_is_said_at_info(caplog: pytest.LogCaptureFixture,
                                                                play_at: float) -> None:
    physics = drummer()
    node: Any = SimpleNamespace(settings=PhysicsNodeSettings(score=str(SCORE), play_at=play_at), core=physics,
                                clock=SimpleNamespace(now=lambda: 4.411))
    with caplog.at_level(logging.INFO, logger="batteur.physics.score"):
        start_score(node)
    physics.close()
    (line,) = late_lines(caplog)
    assert line[0] == logging.INFO, line  # was: WARNING on every default rig start
    assert f"play at rig time {play_at:.3f} s asked at 4.411 s" in line[1] and "late)" in line[1]  # the same facts


def test_a_remote_play_for_a_time_already_past_is_still_a_warning(caplog: pytest.LogCaptureFixture) -> None:
    physics = drummer()
    with caplog.at_level(logging.INFO, logger="batteur.physics.score"):
        physics.score_player.play(1.0, 0.0, 4.411)  # /batteur/score/transport play 1.0 0, arriving at 4.411 s
    physics.close()
    (line,) = late_lines(caplog)
    assert line[0] == logging.WARNING and "already past" in line[1], line
