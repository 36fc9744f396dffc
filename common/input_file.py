"""Whether a path given for an input file is a regular file, said in one line, without opening it.

A folder, a device or a pipe given where a file is read was "no such file" for some readers and blocked others for
good (opening a pipe waits for a writer): every loader asks :func:`file_problem` first, so each names it the same
way (``skeleton.bvh: not a regular file but a pipe (FIFO); give a BVH file``).
"""

from __future__ import annotations

import stat
from collections.abc import Callable
from pathlib import Path

NO_SUCH_FILE = "no such file"
""":func:`file_problem` of a path that is not there (a loader with its own words for it compares with this)."""

NOT_FILES: tuple[tuple[Callable[[int], bool], str], ...] = (
    (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"), (stat.S_ISFIFO, "a pipe (FIFO)"),
    (stat.S_ISSOCK, "a socket"),
)
"""What a path that is neither a file nor a folder may be, by its mode, as :func:`file_problem` names it."""


def kind_of(mode: int) -> str:
    """What a path of this ``st_mode`` is when it is neither a regular file nor a folder (``"something else"`` for
    a kind not named in :data:`NOT_FILES`)."""
    return next((name for test, name in NOT_FILES if test(mode)), "something else")


def file_problem(path: Path, what: str, give: str | None = None) -> str | None:
    """Why ``path`` cannot be read as ``what`` (``"a BVH file"``), said after the path; None for a regular file (or
    a link to one).

    ``no such file``; ``is a folder, not a BVH file``; ``not a regular file but a pipe (FIFO); give a BVH file``
    (``give``: what to ask for instead, ``what`` by default); ``cannot read it (Permission denied)`` for a folder
    on the way that cannot be searched or a loop of links. The path is only ``stat``-ed: nothing is opened.
    """
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        return NO_SUCH_FILE
    except OSError as exc:
        return f"cannot read it ({exc.strerror or exc})"
    if stat.S_ISREG(mode):
        return None
    if stat.S_ISDIR(mode):
        return f"is a folder, not {what}"
    return f"not a regular file but {kind_of(mode)}; give {give or what}"
