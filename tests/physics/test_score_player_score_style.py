"""A text score's `grip` and `nuance` directives reach the live score player: loading it plans with them and sets
the hands' grip, as a /batteur/score/style would; a later style message wins; a score without them changes
nothing."""

from __future__ import annotations

import logging
from pathlib import Path

import pytest

from common.gesture.plan import Grip, Nuance
from common.kit import load_kit
from services.physics.core import PhysicsCore

STYLED = "grip french\nnuance staccato\ntempo 120\nmeter 4/4\nSN |x.x.|\n"


def test_a_loaded_score_style_plans_and_sets_the_hands_until_a_style_message(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    (tmp_path / "styled.txt").write_text(STYLED)
    (tmp_path / "plain.txt").write_text(STYLED.replace("grip french\nnuance staccato\n", ""))
    core = PhysicsCore(scene="drummer", kit=load_kit("default"), grip="german", pose_rate_hz=0)
    try:
        player = core.score_player
        player.library = [tmp_path]
        with caplog.at_level(logging.INFO, logger="batteur.physics.score"):
            player.load("styled.txt")
        assert (player.grip, player.nuance) == (Grip.FRENCH, Nuance.STACCATO)
        assert core.scene.grip == {"left": "french", "right": "french"}
        said = [r.getMessage() for r in caplog.records if "asks for" in r.getMessage()]
        assert said == ["score styled.txt asks for grip french and nuance staccato: planning with the french grip, "
                        "staccato"]
        planner = player._planner(list(player.score.events), player.score.beats, 1.0)  # what a play would plan
        assert planner.args[-2:] == (Grip.FRENCH, Nuance.STACCATO)
        player.set_style("german", "legato", "viterbi", "none")  # a later style message wins
        assert (player.grip, player.nuance) == (Grip.GERMAN, Nuance.LEGATO)
        assert core.scene.grip == {"left": "german", "right": "german"}
        player.load("plain.txt")  # no directives: the style stays
        assert (player.grip, player.nuance) == (Grip.GERMAN, Nuance.LEGATO)
    finally:
        core.close()
