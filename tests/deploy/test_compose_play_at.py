"""compose.yaml passes ``BATTEUR_PLAY_AT`` to physics (empty by default: the score, if any, is only loaded), so
``BATTEUR_SCORE=/scores/groove.mid BATTEUR_PLAY_AT=0 docker compose up`` plays it as soon as physics can. It was not
passed (physics refused an empty value, so it had no default meaning "none"): docs/deployment.md sent the user to a
compose.override.yaml or to ``batteur send ... transport play``."""

from __future__ import annotations

import pytest

from tests.deploy.test_compose import ROOT
from tests.deploy.test_compose_healthcheck_score import _physics_settings

pytestmark = pytest.mark.timeout(240)


def test_physics_gets_play_at_empty_by_default() -> None:
    default = _physics_settings({})  # BATTEUR_PLAY_AT passed empty: not set
    assert default["play_at"] is None and default["score"] == ""
    chosen = _physics_settings({"BATTEUR_SCORE": "/scores/groove.mid", "BATTEUR_PLAY_AT": "0"})
    assert chosen["score"] == "/scores/groove.mid" and chosen["play_at"] == 0.0


def test_play_at_is_documented_in_the_variables_table() -> None:
    text = (ROOT / "docs" / "deployment.md").read_text(encoding="utf-8")
    assert any(line.startswith("| `BATTEUR_PLAY_AT` |") for line in text.splitlines())
