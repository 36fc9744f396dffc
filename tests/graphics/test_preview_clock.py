"""A standalone preview (``batteur graphics --preview-score``) needs no physics: it is its own clock master, so it
no longer waits 3 s at start and warns "no clock master (physics) ... rig time will jump"."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

import common.runtime
from common.config import NodeSettings
from services.graphics import node as graphics_node

TINY_SCORE = Path(__file__).with_name("tiny_score.txt")


class StartedNode:
    """Stands in for the runtime's Node: records the settings the graphics node would run with."""

    started: list[NodeSettings] = []

    def __init__(self, core: Any, settings: NodeSettings, **kwargs: Any) -> None:
        self.started.append(settings)
        self.failed = False

    def request_stop(self) -> None:
        """What a signal once the core is made calls (common.runtime.run_node)."""

    async def run(self, **kwargs: Any) -> None:
        return None


def clock_master_of(argv: list[str], monkeypatch: pytest.MonkeyPatch) -> str:
    StartedNode.started = []
    monkeypatch.setattr(common.runtime, "Node", StartedNode)
    assert graphics_node.main(["--no-discovery", "--http-port", "0", *argv]) == 0
    (settings,) = StartedNode.started
    return settings.clock_master


def test_a_score_preview_is_its_own_clock_master(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("BATTEUR_CLOCK_MASTER", raising=False)
    monkeypatch.delenv("BATTEUR_CONFIG", raising=False)
    assert clock_master_of(["--preview-score", str(TINY_SCORE)], monkeypatch) == "self"


def test_a_clock_master_the_user_set_is_kept(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("BATTEUR_CONFIG", raising=False)
    monkeypatch.delenv("BATTEUR_CLOCK_MASTER", raising=False)
    assert clock_master_of(["--preview-score", str(TINY_SCORE), "--clock-master", "sound"], monkeypatch) == "sound"
    monkeypatch.setenv("BATTEUR_CLOCK_MASTER", "interaction")
    assert clock_master_of(["--preview-score", str(TINY_SCORE)], monkeypatch) == "interaction"


def test_the_live_view_still_follows_physics(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("BATTEUR_CLOCK_MASTER", raising=False)
    monkeypatch.delenv("BATTEUR_CONFIG", raising=False)
    assert clock_master_of([], monkeypatch) == "physics"


def test_the_helper_leaves_other_settings_alone() -> None:
    settings = graphics_node.GraphicsNodeSettings(preview_score=str(TINY_SCORE), port=0)
    before = settings.model_dump(exclude={"clock_master"})
    graphics_node.own_clock_for_preview(settings)
    assert settings.clock_master == "self" and settings.model_dump(exclude={"clock_master"}) == before


def test_the_synthetic_drummer_is_its_own_clock_master(monkeypatch: pytest.MonkeyPatch) -> None:
    """``--synthetic`` (a demo without physics) also waited 3 s for physics and warned that rig time would jump."""
    monkeypatch.delenv("BATTEUR_CLOCK_MASTER", raising=False)
    monkeypatch.delenv("BATTEUR_CONFIG", raising=False)
    assert clock_master_of(["--synthetic"], monkeypatch) == "self"
    assert clock_master_of(["--synthetic", "--clock-master", "physics"], monkeypatch) == "physics"
