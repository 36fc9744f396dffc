"""compose.yaml: healthchecks with room on a loaded machine, and a score the physics container loads.

* A healthcheck runs ``batteur ls --node ... --timeout 2``; a deployment walkthrough timed it at 1.9-6.3 s on a
  loaded machine (Python's start-up and imports, then up to 2 s waiting for the Health), against compose's
  ``timeout: 5s``: a healthy node could be marked unhealthy. The compose timeout is 10 s.
* ``BATTEUR_SCORE`` reaches physics (empty: no score, which physics takes as none), ``./scores`` is mounted as its
  score library (``BATTEUR_SCORE_DIR=/scores``), read-only; docs/deployment.md says how to play it.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from tests.deploy.test_compose import ROOT, compose_config
from tests.deploy.test_compose_qa import _seconds

pytestmark = pytest.mark.timeout(180)

ROLES = ("physics", "interaction", "sound", "graphics")
SLOWEST_CHECK_S = 6.3
"""The slowest healthcheck the walkthrough timed on a loaded machine, seconds."""


def test_each_healthcheck_has_room_for_a_loaded_machine() -> None:
    services = compose_config()["services"]
    for name in ROLES:
        check = services[name]["healthcheck"]
        test = check["test"]
        ls_timeout_s = float(test[test.index("--timeout") + 1])
        timeout_s = _seconds(check.get("timeout"), 30.0)
        assert timeout_s >= 10.0, (name, check.get("timeout"))
        assert timeout_s > max(SLOWEST_CHECK_S, ls_timeout_s), name
        assert timeout_s <= _seconds(check.get("interval"), 30.0), name  # one check at a time


def _physics_settings(env: dict[str, str]) -> dict[str, object]:
    """What ``batteur physics`` makes of the container's command and environment (no discovery, nothing bound)."""
    physics = compose_config(env)["services"]["physics"]
    given = {k: str(v) for k, v in physics["environment"].items()}
    full = {k: v for k, v in os.environ.items() if not k.startswith("BATTEUR_")}
    full.update(given)
    command = [str(a) for a in physics["command"]]
    result = subprocess.run([sys.executable, "-m", "batteur", *command, "--no-discovery", "--show-settings"],
                            capture_output=True, text=True, env=full, timeout=120, cwd=str(ROOT), check=False)
    assert result.returncode == 0, result.stderr
    shown: dict[str, object] = json.loads(result.stdout)
    return shown


def test_the_physics_container_gets_the_score_and_its_library() -> None:
    physics = compose_config()["services"]["physics"]
    mounts = [v if isinstance(v, str) else f"{v.get('source')}:{v.get('target')}:{'ro' if v.get('read_only') else ''}"
              for v in physics["volumes"]]
    assert any(m.startswith(str(ROOT / "scores") + ":/scores") and m.endswith(":ro") for m in mounts), mounts
    default = _physics_settings({})
    assert default["score"] == "" and default["play_at"] is None  # none: the drummer idles, as before
    assert default["score_dir"] == ["/scores"]
    chosen = _physics_settings({"BATTEUR_SCORE": "/scores/groove.mid"})
    assert chosen["score"] == "/scores/groove.mid"


def test_the_scores_folder_is_documented() -> None:
    text = " ".join((ROOT / "docs" / "deployment.md").read_text(encoding="utf-8").split())
    assert "BATTEUR_SCORE" in text and "./scores" in text and "/batteur/score/transport play" in text
