"""The README points to the live-control guide (driving a rig from one's own software over OSC), and every doc it
names exists. A musician sending OSC from python-osc found docs/live-control.md only by listing docs/."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "README.md"


def test_the_readme_names_the_live_control_guide_and_only_docs_that_exist() -> None:
    named = set(re.findall(r"`(docs/[\w./-]+\.md)`", README.read_text(encoding="utf-8")))
    assert "docs/live-control.md" in named
    assert all((ROOT / path).is_file() for path in named), sorted(p for p in named if not (ROOT / p).is_file())
