"""``batteur echo --node HOST:PORT`` says when its node goes away and when it comes back.

A teacher left ``batteur echo`` running while the rig was stopped: it went on in silence, as if the node had
nothing to say. Echo now asks each node for its Health every second (a Hello from an endpoint of its own, as
``batteur ls``) and says on standard error when a node that answered has not for three of them (stopped, or out of
reach), that it keeps asking, and when it answers again (subscribed again at once: a node forgets its subscribers
when it stops). The node copies echo's Hellos and its answers like any message: they are not printed. A real
interaction node on loopback (no discovery), stopped and started again on the same port.
"""

from __future__ import annotations

import queue
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO

import pytest

from batteur.tools import send
from tests.ports import free_port

pytestmark = pytest.mark.timeout(240)


def start_node(port: int, log_path: Path) -> subprocess.Popen[bytes]:
    """An interaction node on 127.0.0.1:``port`` (no discovery, its own clock), once it says it listens."""
    said = f"listening on 127.0.0.1:{port} (rate"
    before = log_path.read_text(errors="replace").count(said) if log_path.exists() else 0
    with open(log_path, "ab") as log:
        proc = subprocess.Popen([sys.executable, "-m", "batteur", "interaction", "--port", str(port),
                                 "--no-discovery", "--no-oscquery", "--clock-master", "self"],
                                stdout=subprocess.DEVNULL, stderr=log)
    deadline = time.monotonic() + 60
    while proc.poll() is None and time.monotonic() < deadline:
        if log_path.read_text(errors="replace").count(said) > before:
            return proc
        time.sleep(0.1)
    proc.kill()
    raise AssertionError(f"the interaction node never said it listens: {log_path.read_text(errors='replace')}")


def lines_of(stream: IO[str]) -> queue.Queue[str]:
    """The lines of ``stream`` as they come, read by a thread."""
    lines: queue.Queue[str] = queue.Queue()

    def read() -> None:
        for line in stream:
            lines.put(line.rstrip("\n"))

    threading.Thread(target=read, daemon=True).start()
    return lines


def wait_for(lines: queue.Queue[str], seen: list[str], wanted: Callable[[str], bool], timeout_s: float = 60) -> str:
    """The first line of ``lines`` that is ``wanted`` (every line read kept in ``seen``)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            line = lines.get(timeout=0.2)
        except queue.Empty:
            continue
        seen.append(line)
        if wanted(line):
            return line
    raise AssertionError(f"not said within {timeout_s:g} s: {seen}")


@pytest.fixture
def node_port(tmp_path: Path) -> Iterator[tuple[int, Path]]:
    yield free_port(), tmp_path / "node.log"


def test_echo_says_its_node_went_away_and_came_back(node_port: tuple[int, Path]) -> None:
    port, log_path = node_port
    node = start_node(port, log_path)
    echo = subprocess.Popen([sys.executable, "-m", "batteur", "echo", "/batteur/*", "--node", f"127.0.0.1:{port}",
                             "--duration", "200"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert echo.stdout is not None and echo.stderr is not None
    out, err = lines_of(echo.stdout), lines_of(echo.stderr)
    said: list[str] = []
    printed: list[str] = []
    try:
        wait_for(err, said, lambda line: line.startswith("batteur echo: printing /batteur/*"))
        node.terminate()
        node.wait(timeout=30)
        gone = wait_for(err, said, lambda line: "went away" in line)
        assert gone.startswith("batteur echo: node interaction-") and f"at 127.0.0.1:{port} went away" in gone, gone
        assert "still asking for it every 1 s: its messages are printed again if it comes back" in gone, gone
        node = start_node(port, log_path)
        back = wait_for(err, said, lambda line: "is back" in line)
        assert back.startswith("batteur echo: node interaction-") and back.endswith("is back; subscribed again")
        # subscribed again: what the node receives is copied to echo once more
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            assert send.main(["/batteur/hello", "cli", "tester", "1", "9", "--to", f"127.0.0.1:{port}"]) == 0
            try:
                wait_for(out, printed, lambda line: line.startswith("/batteur/hello 'cli' 'tester'"), timeout_s=1)
                break
            except AssertionError:
                continue
        else:
            raise AssertionError(f"nothing copied after the node came back: {printed}, {said}")
    finally:
        echo.terminate()
        echo.wait(timeout=30)
        node.terminate()
        node.wait(timeout=30)
    # echo's own Hellos (one a second) and the node's answers to them, copied back, are not the rig's messages
    assert not [line for line in printed if "batteur-echo-" in line], printed
    hellos_sent = sum(1 for line in printed if line.startswith("/batteur/hello 'cli' 'tester'"))
    assert sum(1 for line in printed if line.startswith("/batteur/health")) <= hellos_sent, printed
