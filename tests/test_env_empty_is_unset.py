"""An empty ``BATTEUR_<NAME>`` variable means the setting is not set, as most tools treat an empty variable: the
node's default (or its config file's value) applies. Physics refused ``BATTEUR_PLAY_AT=`` ("unable to parse string
as a number"), so compose.yaml could not pass it with an empty default (``${BATTEUR_PLAY_AT:-}``); an empty
``BATTEUR_HOST``, ``BATTEUR_PORT``, ``BATTEUR_INTERFACES``, ``BATTEUR_DISCOVERY`` ... were refused the same way.

Every setting of every node is tried (settings only: no node runs, nothing is bound)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from common.config import NodeSettings, load_settings
from services.graphics.node import GraphicsNodeSettings
from services.interaction.node import InteractionSettings
from services.physics.node import PhysicsNodeSettings
from services.sound.node import SoundNodeSettings

ROOT = Path(__file__).resolve().parents[1]
NODES: dict[str, type[NodeSettings]] = {"physics": PhysicsNodeSettings, "interaction": InteractionSettings,
                                        "sound": SoundNodeSettings, "graphics": GraphicsNodeSettings}
CASES = [(role, name) for role, cls in NODES.items() for name in cls.model_fields]


@pytest.fixture(autouse=True)
def _no_batteur_variables(monkeypatch: pytest.MonkeyPatch) -> None:
    for name in list(os.environ):
        if name.startswith("BATTEUR_"):
            monkeypatch.delenv(name)


@pytest.mark.parametrize(("role", "name"), CASES, ids=[f"{r}-{n}" for r, n in CASES])
def test_an_empty_variable_leaves_the_setting_unset(role: str, name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    cls = NODES[role]
    default = load_settings({}, None, {"role": role}, cls)
    monkeypatch.setenv(f"BATTEUR_{name.upper()}", "")
    settings = load_settings({}, None, {"role": role}, cls)  # raised SettingsError for most settings
    assert settings.model_fields_set == default.model_fields_set  # as if not set at all
    if name != "epoch":  # its default is the time it is read at
        assert getattr(settings, name) == getattr(default, name)


def test_an_empty_variable_leaves_the_config_file_s_value(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    config = tmp_path / "rig.yaml"
    config.write_text("port: 9001\nphysics:\n  play_at: 2.5\n  score: groove.mid\n")
    monkeypatch.setenv("BATTEUR_PORT", "")
    monkeypatch.setenv("BATTEUR_PLAY_AT", "")
    settings = load_settings({}, config, {"role": "physics"}, PhysicsNodeSettings)
    assert isinstance(settings, PhysicsNodeSettings)
    assert (settings.port, settings.play_at) == (9001, 2.5)


def test_physics_starts_with_an_empty_play_at_variable() -> None:
    """The command compose.yaml's physics runs with ``BATTEUR_PLAY_AT: ${BATTEUR_PLAY_AT:-}``."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("BATTEUR_")}
    env.update(BATTEUR_PLAY_AT="", BATTEUR_SCORE="")
    result = subprocess.run([sys.executable, "-m", "batteur", "physics", "--no-discovery", "--show-settings"],
                            capture_output=True, text=True, env=env, timeout=120, cwd=str(ROOT), check=False)
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["play_at"] is None
