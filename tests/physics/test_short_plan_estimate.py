"""Background plans (services/physics/score_player.py) are spliced an estimated planning time after their message;
one ready after its splice time is planned again with the time it measured. Until 6 Dec night only plans of at
least ``PLAN_MEASURED_NOTES`` (20) notes were timed, so a short score on a loaded machine kept its first guess
(22 ms for 4 notes): each retry was as late as the first, and after ``MAX_PLAN_RETRIES`` it was not played. A short
plan's time now counts (whole: it is mostly overhead).

The planning time is made up, not measured: the player's clock (``time.perf_counter``) says each plan took 0.4 s,
and the rig clock moves on as much before the plan is looked at, so nothing depends on the machine's speed.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

import services.physics.score_player as score_player_module
from common.messages.score import ScoreLoad, ScoreTransport
from services.physics.node import LivePhysicsCore
from services.physics.score_player import MAX_PLAN_RETRIES, PLAN_MEASURED_NOTES

PLAN_TOOK_S = 0.4
"""How long each plan takes by the player's clock (and the rig's), seconds."""
SHORT_SCORE = """\
tempo 120
meter 4/4
SN |x.x.x.x.|
"""
"""Four snare notes: a plan under PLAN_MEASURED_NOTES notes."""


class _PlanClock:
    """Stands in for the ``time`` module in the score player: ``perf_counter`` is what the test sets."""

    def __init__(self) -> None:
        self.now = 0.0

    def perf_counter(self) -> float:
        return self.now


@pytest.fixture
def plan_clock(monkeypatch: pytest.MonkeyPatch) -> Iterator[_PlanClock]:
    clock = _PlanClock()
    monkeypatch.setattr(score_player_module, "time", clock)
    yield clock


@pytest.fixture
def core(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[LivePhysicsCore]:
    (tmp_path / "short.txt").write_text(SHORT_SCORE, encoding="utf-8")
    settings: dict[str, Any] = {"scene": "drummer", "grip": "german", "pose_rate_hz": 0, "mode": "live"}
    physics = LivePhysicsCore(planner="thread", **settings)
    assert physics.score_player.wait_loaded(120.0)  # as the node before it listens (play: refused meanwhile)
    physics.score_player.library = [tmp_path]
    # each plan waits until the test looks for it: a plan of four notes in a thread could finish before the message
    # that started it returned, and be spliced then, at the made-up clock's start (no time taken, never late)
    released = threading.Event()
    plan = physics.score_player._planner

    def held(*args: Any, **kwargs: Any) -> Any:
        planning = plan(*args, **kwargs)

        def when_released() -> Any:
            released.wait(60.0)
            return planning()

        return when_released

    monkeypatch.setattr(physics.score_player, "_planner", held)
    physics.score_player.release = released  # type: ignore[attr-defined]
    yield physics
    released.set()
    physics.close()


def test_a_short_score_late_under_load_is_planned_again_with_its_measured_time_and_plays(
        core: LivePhysicsCore, plan_clock: _PlanClock) -> None:
    player = core.score_player
    now = 1.0
    core.handle(ScoreLoad(path="short.txt"), now, "")
    assert player.score is not None and len(player.score.events) < PLAN_MEASURED_NOTES
    assert core.handle(ScoreTransport(action="play", time=0.0, position=0.0), now, "") == []  # "at once"
    assert player.busy  # the play's plan is in flight (held)
    player.release.set()  # type: ignore[attr-defined]
    for _ in range(1 + MAX_PLAN_RETRIES):  # the first plan, then each retry
        assert player.wait(60.0)
        plan_clock.now += PLAN_TOOK_S  # the plan took that long, and so much rig time went by
        now += PLAN_TOOK_S
        core.step(now)  # looks at the ready plan: spliced, or planned again
        if not player.busy:
            break
    assert player.replanned_late == 1  # the first guess was too short; the retry used the time measured
    assert player.plans == 1 and player.state == "playing" and not core.rejected
