"""``batteur sound`` run alone, given no ``--port``, listens on any free port: it says which, and the command that
runs it where Pd looks for it (9103, on its own clock). Given a port (as ``batteur rig`` gives every node), it
says nothing of the kind."""

from __future__ import annotations

import os
import selectors
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.ports import free_port

ROOT = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.timeout(120)


def _log_until_listening(*args: str, wait_for_port_line: bool = False) -> list[str]:
    """Run ``batteur sound ARGS`` (no discovery, no OSCQuery, no sound card) until it says it listens (and up to
    3 s after, for the lines its start logs next), or, with ``wait_for_port_line``, until it says which port it
    took; its log lines."""
    proc = subprocess.Popen([sys.executable, "-m", "batteur", "sound", "--no-discovery", "--no-oscquery",
                             "--device", "none", "--clock-master", "self", *args],
                            cwd=ROOT, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            text=True)
    lines: list[str] = []
    assert proc.stderr is not None
    fd = proc.stderr.fileno()  # read unbuffered: a buffered readline takes in more lines than it returns, and
    sel = selectors.DefaultSelector()  # select() would then wait on a pipe already drained into the buffer
    sel.register(fd, selectors.EVENT_READ)
    pending = b""
    try:
        deadline = time.monotonic() + 90
        settle: float | None = None
        done = False
        while not done and time.monotonic() < (settle or deadline):
            if not sel.select(timeout=0.2):
                continue
            chunk = os.read(fd, 65536)
            if not chunk:
                break
            pending += chunk
            *complete, pending = pending.split(b"\n")
            for raw in complete:
                line = raw.decode(errors="replace")
                lines.append(line)
                if "no --port was given" in line:
                    done = True  # what the first test waits for (logged right after the node listens)
                if settle is None and "listening on" in line and not wait_for_port_line:
                    settle = time.monotonic() + 3.0
        assert any("listening on" in line for line in lines), "the sound node never listened:\n" + "\n".join(lines)
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        sel.close()
    return lines


def test_sound_alone_says_the_port_it_took_and_the_command_for_pd() -> None:
    lines = _log_until_listening(wait_for_port_line=True)
    said = [line for line in lines if "a free port taken because no --port was given" in line]
    assert len(said) == 1, "\n".join(lines)
    listening = next(line for line in lines if "listening on" in line)
    port = said[0].split("listens on port ")[1].split(",")[0]
    assert f":{port} " in listening  # the port it really took
    assert "batteur sound --port 9103 --clock-master self" in said[0]


def test_sound_given_a_port_says_nothing_of_pd() -> None:
    port = free_port()
    lines = _log_until_listening("--port", str(port))
    assert any(f":{port} " in line for line in lines if "listening on" in line), "\n".join(lines)
    assert not [line for line in lines if "no --port was given" in line]
