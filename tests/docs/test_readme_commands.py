"""The README's command table names every ``batteur`` subcommand (``batteur --help`` lists the same)."""

from __future__ import annotations

import re
from pathlib import Path

from batteur.cli import COMMANDS

README = Path(__file__).resolve().parents[2] / "README.md"


def table_commands(text: str) -> set[str]:
    """The subcommands the README's "Commands" table names (`batteur NAME ...` in its first column)."""
    section = text.split("## Commands", 1)[1].split("\n## ", 1)[0]
    rows = [line.split("|")[1] for line in section.splitlines() if line.startswith("| `batteur")]
    names: set[str] = set()
    for cell in rows:  # `batteur physics`, `interaction`, `sound`: a name alone continues the row's list
        for with_prefix, alone in re.findall(r"`batteur ([a-z-]+)|`([a-z-]+)`", cell):
            names.add(with_prefix or alone)
    return names


def test_every_subcommand_is_in_the_readme_table() -> None:
    missing = set(COMMANDS) - table_commands(README.read_text(encoding="utf-8"))
    assert not missing, f"README.md's Commands table lacks: {', '.join(sorted(missing))}"
