"""The shipped kits as a ``--kit`` option's help names them (render, evaluate, rig, graphics).

Read from the kits folder (:data:`common.kit.KITS_DIR`), not written here: a kit added there is listed. Each kit is
described by what its file says at the top level (``handedness: left``: mirrored for a left-handed drummer,
``double_pedal: true``), read as text, not validated: a command's parser is built on every run, the help is
shown on few.
"""

from __future__ import annotations

import re
from pathlib import Path

from common.kit import KITS_DIR

KITS_DOC = 'docs/score-format.md "Kits"'
"""Where the kit file format is documented."""


def _top_level(text: str, key: str) -> str | None:
    """The value of a top-level ``key: value`` line of a YAML kit file, None if it has none."""
    found = re.search(rf"^{re.escape(key)}:\s*(\S+)", text, flags=re.MULTILINE)
    return None if found is None else found.group(1)


def describe_kit(path: Path) -> str:
    """``left_handed (mirrored, for a left-handed drummer)``, ``double_pedal (double bass pedal)``, ``default``: a
    shipped kit by its name and what sets it apart."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return path.stem
    notes = []
    if _top_level(text, "handedness") == "left":
        notes.append("mirrored, for a left-handed drummer")
    if _top_level(text, "double_pedal") == "true":
        notes.append("double bass pedal")
    return f"{path.stem} ({', '.join(notes)})" if notes else path.stem


def shipped_kits(folder: Path = KITS_DIR) -> list[str]:
    """The shipped kits' names with what sets each apart (:func:`describe_kit`), by name."""
    return [describe_kit(path) for path in sorted(folder.glob("*.yaml"))]


def kit_help(default: str | None = None, what: str = "kit name or YAML/JSON file") -> str:
    """A ``--kit`` option's help: ``what``, the shipped kits, where the format is documented, the ``default``
    (None: not said, a service's parser adds its own)."""
    said = "" if default is None else f" (default: {default})"
    return f"{what}: a shipped kit, {', '.join(shipped_kits())}, or a kit file of your own ({KITS_DOC}){said}"
