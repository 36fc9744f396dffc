"""Reading what a command shows on a pseudo-terminal, for the Ctrl-C tests that run a command as a terminal
would (its own process group, stderr on a pty)."""

from __future__ import annotations

import os
import select


def read_terminal(fd: int, timeout_s: float) -> str:
    """What the terminal ``fd`` shows within ``timeout_s`` seconds (empty once the other side is closed)."""
    ready, _, _ = select.select([fd], [], [], timeout_s)
    if not ready:
        return ""
    try:
        return os.read(fd, 65536).decode(errors="replace")
    except OSError:  # EIO: every process holding the terminal has exited
        return ""
