"""Fixtures shared by the physics tests."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

import common.gesture.planner as planner_module
from services.physics.core import PhysicsCore, PhysicsSettings
from services.physics.score_player import ScorePlayer


@pytest.fixture(scope="module")
def drummer() -> Iterator[PhysicsCore]:
    """One drummer core (no poses sent) per test module: building the scene takes about a second."""
    core = PhysicsCore(scene="drummer", pose_rate_hz=0)
    yield core
    core.close()


@pytest.fixture
def gate(monkeypatch: pytest.MonkeyPatch) -> Iterator[threading.Event]:
    """The planner waits until the returned event is set (a plan that takes as long as the test wants); set after
    60 s at the latest, so a core that waited for it fails the test instead of hanging it."""
    original = planner_module.plan_gestures
    release = threading.Event()

    def held(*args: Any, **kwargs: Any) -> Any:
        release.wait()
        return original(*args, **kwargs)

    monkeypatch.setattr(planner_module, "plan_gestures", held)
    safety = threading.Timer(60.0, release.set)
    safety.start()
    try:
        yield release
    finally:
        release.set()
        safety.cancel()


@pytest.fixture
def library_player(tmp_path: Path) -> Iterator[ScorePlayer]:
    """A live strike-scene core's score player whose score library is the empty folder ``tmp_path / "lib"``."""
    core = PhysicsCore(PhysicsSettings(scene="strike", mode="live"))
    core.score_player.library = [tmp_path / "lib"]
    (tmp_path / "lib").mkdir()
    try:
        yield core.score_player
    finally:
        core.close()
