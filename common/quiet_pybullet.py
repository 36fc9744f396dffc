"""PyBullet, imported without the line its C library prints on stderr as it loads (``pybullet build time: ...``).

Every module that uses PyBullet imports it from here: that line came before every command's output, even
``batteur render --help``, and made an error two lines instead of one (README, "Exit status"). Only that line
is dropped: anything else written to stderr while the library loads (another thread's log line) is passed on.
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
from collections.abc import Iterator
from typing import IO

BANNER = b"pybullet build time:"
"""How the line the C library prints as it is loaded starts."""

__all__ = ["BulletClient", "pybullet"]


@contextlib.contextmanager
def banner_dropped(fd: int = 2) -> Iterator[None]:
    """Run the body with file descriptor ``fd`` (stderr) pointing at a temporary file, then write what the body
    wrote there to the real ``fd``, less the lines starting as :data:`BANNER` (C code writes past ``sys.stderr``:
    only the descriptor catches it). Without the descriptor or a temporary file, the body runs as it is."""
    with contextlib.suppress(AttributeError, ValueError):  # no sys.stderr, or a closed one
        sys.stderr.flush()  # Python's own buffered text goes out before the descriptor moves
    caught = _temporary_file()
    saved = _dup(fd) if caught is not None else None
    if caught is None or saved is None:
        if caught is not None:
            caught.close()
        yield
        return
    with caught:
        os.dup2(caught.fileno(), fd)
        try:
            yield
        finally:
            os.dup2(saved, fd)
            os.close(saved)
            caught.seek(0)
            kept = b"".join(line for line in caught if not line.startswith(BANNER))
            with contextlib.suppress(OSError):  # a stderr gone meanwhile: the lines have nowhere to go
                while kept:
                    kept = kept[os.write(fd, kept):]


def _temporary_file() -> IO[bytes] | None:
    try:
        return tempfile.TemporaryFile()
    except OSError:  # no writable temporary folder
        return None


def _dup(fd: int) -> int | None:
    try:
        return os.dup(fd)
    except OSError:  # a closed stderr
        return None


with banner_dropped():
    import pybullet
    from pybullet_utils.bullet_client import BulletClient
