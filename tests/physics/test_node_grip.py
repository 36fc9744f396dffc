"""The grip the drummer's hands hold and the grip its gestures are planned with.

The live node (``batteur physics``, which ``batteur rig`` starts) holds and plans the grip ``batteur render`` does,
so a score played live is played as it renders. Hands holding a grip the gesture database has no units for
(american, traditional), or another grip than the planned one after a ``/batteur/physics/grip``, are said once in
the log, naming the grip the gestures are planned with; ``/batteur/score/style`` sets both and is quiet.
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import pytest

from batteur import render
from common.messages.physics import PhysicsGrip
from common.messages.score import GestureStyle, ScoreTransport
from services.physics.core import PhysicsCore
from services.physics.drummer import DrummerScene
from services.physics.node import PhysicsNodeSettings, make_core

SCORE = Path(__file__).parents[1] / "render" / "short_groove.txt"
SENDER = "127.0.0.1:9"


def test_the_node_s_drummer_holds_and_plans_the_grip_batteur_render_does(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("BATTEUR_GRIP", raising=False)
    monkeypatch.delenv("BATTEUR_CONFIG", raising=False)
    rendered = render.options_from(render.build_parser().parse_args([str(SCORE), "-o", "out"])).styled().grip
    core = make_core(PhysicsNodeSettings(discovery=False), argparse.Namespace())
    try:
        assert isinstance(core.scene, DrummerScene)
        assert core.scene.grip == {"left": rendered, "right": rendered}
        assert core.score_player.grip.value == rendered
    finally:
        core.close()


def _grip_warnings(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING and "grip" in r.getMessage()]


def _play(core: PhysicsCore, now: float) -> None:
    """Play the loaded score at once from its start (rig time ``now``, s), then stop it (nothing is refused)."""
    core.handle(ScoreTransport(action="play", time=0.0, position=0.0), now, SENDER)
    assert core.score_player.state == "playing"
    core.handle(ScoreTransport(action="stop", time=0.0, position=0.0), now + 0.01, SENDER)
    assert core.rejected_total == 0, dict(core.rejected)


def test_hands_in_a_grip_the_planner_has_no_units_for_are_logged_once_naming_the_planned_grip(
        caplog: pytest.LogCaptureFixture) -> None:
    core = PhysicsCore(scene="drummer", grip="american", pose_rate_hz=0)
    try:
        core.score_player.load(SCORE, trusted=True)
        with caplog.at_level(logging.WARNING, logger="batteur.physics"):
            _play(core, 0.0)
            _play(core, 0.1)  # the same hands and plan again: not repeated
        warnings = _grip_warnings(caplog)
        assert len(warnings) == 1, warnings
        assert "hands hold the american grip" in warnings[0]
        assert "planned with the german grip" in warnings[0]
    finally:
        core.close()


def test_a_live_grip_change_of_the_hands_keeps_the_planned_grip_and_says_so_at_the_next_plan(
        caplog: pytest.LogCaptureFixture) -> None:
    core = PhysicsCore(scene="drummer", grip="german", pose_rate_hz=0)
    player = core.score_player
    try:
        player.load(SCORE, trusted=True)
        with caplog.at_level(logging.WARNING, logger="batteur.physics"):
            _play(core, 0.0)
            assert _grip_warnings(caplog) == []  # german hands, german gestures
            plans = player.plans
            core.handle(PhysicsGrip(hand="left", grip="traditional"), 0.1, SENDER)
            assert player.plans == plans and player.grip.value == "german"  # the hands only: no re-plan
            _play(core, 0.2)
            warnings = _grip_warnings(caplog)
            assert len(warnings) == 1 and "traditional (left) and german (right)" in warnings[0], warnings
            assert "planned with the german grip" in warnings[0]
            # the style sets the hands' grip and the planned one: they agree, nothing more is said
            core.handle(GestureStyle(grip="french", nuance="tenuto", algorithm="viterbi", sticking="none"), 0.3,
                        SENDER)
            assert isinstance(core.scene, DrummerScene)
            assert core.scene.grip == {"left": "french", "right": "french"}
            _play(core, 0.4)
            assert len(_grip_warnings(caplog)) == 1
    finally:
        core.close()
