"""A text score's ``kit`` line on the live score player: the node's kit is fixed at start (a kit change rebuilds
the kit bodies and must reach interaction and sound), so a score naming another kit is still loaded, and played on
the node's kit, but the log says so with a warning (it was played on the other kit in silence); a score naming the
node's own kit, or none, is not warned about."""

from __future__ import annotations

import logging
from pathlib import Path

import pytest

from common.kit import KITS_DIR
from services.physics.score_player import ScorePlayer

BAR = "tempo 120\nmeter 4/4\nSN |x.x.|\n"


def _kit_warnings(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING and "kit" in r.getMessage()]


def test_a_score_naming_another_kit_is_played_on_the_node_s_and_said(
        library_player: ScorePlayer, tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    (tmp_path / "lib" / "pedals.txt").write_text("title two kicks\nkit double_pedal\n" + BAR)
    with caplog.at_level(logging.INFO, logger="batteur.physics.score"):
        library_player.load("pedals.txt")
    assert library_player.score is not None and library_player.score_path is not None
    assert library_player.score_path.name == "pedals.txt"  # loaded all the same
    assert library_player.core.kit.name == "default"  # the kit is not changed live
    said = _kit_warnings(caplog)
    assert len(said) == 1, said
    assert said[0].startswith("score pedals.txt: line 2 asks for kit 'double_pedal': played on this node's kit "
                              "'default'"), said
    assert "restart the rig with --kit double_pedal" in said[0], said


@pytest.mark.parametrize("kit_line", ["kit default\n", "", "kit {default_file}\n"])
def test_a_score_naming_the_node_s_kit_or_none_is_not_warned_about(
        library_player: ScorePlayer, tmp_path: Path, caplog: pytest.LogCaptureFixture, kit_line: str) -> None:
    (tmp_path / "lib" / "same.txt").write_text(kit_line.format(default_file=KITS_DIR / "default.yaml") + BAR)
    with caplog.at_level(logging.INFO, logger="batteur.physics.score"):
        library_player.load("same.txt")
    assert _kit_warnings(caplog) == []


def test_a_kit_file_beside_the_score_is_compared_from_the_score_s_folder(
        library_player: ScorePlayer, tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    """``kit kits/mine.yaml`` is the file in the score's folder (as render reads it), not in the node's."""
    (tmp_path / "lib" / "kits").mkdir()
    (tmp_path / "lib" / "kits" / "mine.yaml").write_text((KITS_DIR / "default.yaml").read_text())
    (tmp_path / "lib" / "mine.txt").write_text("kit kits/mine.yaml\n" + BAR)
    with caplog.at_level(logging.INFO, logger="batteur.physics.score"):
        library_player.load("mine.txt")
    said = _kit_warnings(caplog)
    assert len(said) == 1 and f"asks for kit {str(tmp_path / 'lib' / 'kits' / 'mine.yaml')!r}" in said[0], said
