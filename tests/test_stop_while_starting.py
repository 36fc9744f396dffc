"""A node stopped while its core is being made stops cleanly: ``batteur rig`` stopped while physics was still loading
printed "resource_tracker: There appear to be 10 leaked semaphore objects": SIGTERM killed the node after its core
had started the planning processes (their pools' named semaphores) but before it handled signals, so nothing
closed them and the resource tracker unlinked them, with that warning.

The physics node runs as the rig runs it (``python -m batteur physics``, its own session), on loopback without
discovery; SIGTERM goes once its planning processes run, while it still loads the gesture database and kernels.
"""

from __future__ import annotations

import asyncio
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from common.config import load_settings
from common.runtime import Node, run_node
from tests.null_core import NullCore
from tests.ports import free_port
from tests.waiting import until

pytestmark = [pytest.mark.timeout(300),
              pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc as on Linux")]

ROOT = Path(__file__).parents[1]
PLANNERS = 1
"""Planning processes the live physics core starts while it is made (the first; the spare starts after the first
plan: services/physics/plan_worker.py)."""


def _stat(pid: int) -> list[str] | None:
    """/proc/PID/stat's fields after the command name (state, ppid, pgrp, ...), or None once it is gone."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return text[text.rindex(")") + 2:].split()


def _alive(fields: list[str] | None) -> bool:
    return fields is not None and fields[0] not in "ZX"


def _processes(where: Callable[[list[str]], bool]) -> list[int]:
    """Live processes whose stat fields satisfy ``where``."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            fields = _stat(int(entry.name))
            if _alive(fields) and fields is not None and where(fields):
                found.append(int(entry.name))
    return found


def _planners(node: int) -> list[int]:
    """The node's planning processes (spawned multiprocessing workers; not its resource tracker)."""
    children = _processes(lambda fields: int(fields[1]) == node)
    return [pid for pid in children if b"spawn_main" in _cmdline(pid)]


def _cmdline(pid: int) -> bytes:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return b""


def _semaphores(pid: int) -> set[str]:
    """The named semaphores (/dev/shm/sem.*) process ``pid`` has mapped."""
    try:
        maps = Path(f"/proc/{pid}/maps").read_text()
    except OSError:
        return set()
    return {line.split()[-1] for line in maps.splitlines() if "/dev/shm/sem." in line}


def test_a_physics_node_stopped_while_its_core_is_made_closes_it_and_exits_cleanly() -> None:
    command = [sys.executable, "-m", "batteur", "physics", "--port", str(free_port()), "--host", "127.0.0.1",
               "--no-discovery", "--no-oscquery", "--pose-rate-hz", "0", "--node-id", "physics-stop-test"]
    node = subprocess.Popen(command, cwd=ROOT, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)  # as the rig starts it
    try:
        assert until(lambda: len(_planners(node.pid)) >= PLANNERS or node.poll() is not None, 120.0, poll_s=0.01)
        assert node.poll() is None, "the node exited before its planning processes ran"
        time.sleep(0.3)  # past the planning pools' own start, into the gesture database's loading
        semaphores = _semaphores(node.pid)
        assert semaphores, "the planning pools' semaphores are not there to check"
        node.send_signal(signal.SIGTERM)
        sent = time.monotonic()
        out, err = node.communicate(timeout=120)  # to the end of its output: planners and tracker gone too
        stopped_s = time.monotonic() - sent
    finally:
        if node.poll() is None:
            os.killpg(node.pid, signal.SIGKILL)
            node.wait()
    listening = "listening on" in err  # signalled after make_core on a fast machine: an ordinary stop
    print(f"stopped {stopped_s:.2f} s after SIGTERM ({'after' if listening else 'while'} making its core)")
    assert node.returncode == 0, err[-3000:]
    assert "leaked semaphore" not in err, err[-3000:]
    assert not [s for s in semaphores if Path(s).exists()]  # no named semaphore left in /dev/shm either
    assert until(lambda: not _processes(lambda fields: int(fields[2]) == node.pid), 30.0, poll_s=0.01), \
        "a process of the node's group outlived it"


SLOW_MAKE_CORE = """
import os, signal, subprocess, sys, time
from common.runtime import run_node
from tests.null_core import NullCore

def make_core(settings, args):
    helper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(120)"], stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL)
    print(helper.pid, flush=True)
    try:
        os.kill(os.getpid(), getattr(signal, sys.argv[1]))  # the stop comes while the core is being made
        for _ in range(1200):  # loading for two minutes
            time.sleep(0.1)
    except BaseException:  # what any make_core that starts something does: stop it
        helper.terminate()
        helper.wait()
        raise
    return NullCore()

sys.exit(run_node("sound", make_core, ["--no-discovery", "--no-oscquery", "--port", "0"]))
"""


@pytest.mark.parametrize(("signal_name", "said"), [
    ("SIGTERM", "(SIGTERM: a stop request, e.g. batteur rig's on Ctrl-C)"),
    ("SIGINT", "(SIGINT: Ctrl-C)"),
])
def test_any_node_stopped_while_its_core_is_made_stops_at_once_and_cleans_up(signal_name: str, said: str) -> None:
    """Every service's node goes through run_node: a stop while make_core runs does not wait for its end (it
    could be past the rig's stop timeout); make_core unwinds, stops what it started, and the node exits 0, its log
    saying it was asked to stop ("physics stopped while starting (SIGTERM)" after a Ctrl-C on the rig read like a
    crash; a SIGTERM may come from the rig, docker compose or systemd alike)."""
    node = subprocess.run([sys.executable, "-c", SLOW_MAKE_CORE, signal_name], cwd=ROOT, capture_output=True,
                          text=True, timeout=100)  # before the fix: killed by the signal, its helper left running
    helper = int(node.stdout.split()[0])
    try:
        assert node.returncode == 0, node.stderr[-3000:]
        assert f"sound was asked to stop while starting {said}: stopping cleanly before it listened" in node.stderr, \
            node.stderr[-3000:]
        assert "sound stopped while starting" not in node.stderr
        assert "listening on" not in node.stderr
        assert not _alive(_stat(helper))
    finally:
        if _alive(_stat(helper)):
            os.kill(helper, signal.SIGKILL)


class ClosingCore(NullCore):
    closed = False

    def close(self) -> None:
        self.closed = True


def test_a_node_asked_to_stop_before_it_runs_closes_its_core_without_listening() -> None:
    """A signal that comes once the core is made, before the node's event loop handles signals, asks the node to
    stop: it must not be lost (the node would run on, deaf to the stop it was sent)."""
    core = ClosingCore()
    node = Node(core, load_settings({"role": "sound", "discovery": False, "oscquery": False}))  # type: ignore[arg-type]
    node.request_stop()
    asyncio.run(asyncio.wait_for(node.run(), 60.0))
    assert core.closed and node.endpoint is None and node.stopped.is_set()


def test_a_core_the_node_refuses_is_closed_and_named(capsys: pytest.CaptureFixture[str]) -> None:
    """A core whose rate the node refuses (NaN Hz) is closed and the node exits 2 with one line (it was a
    traceback, the core's processes left to the interpreter's exit)."""
    core = ClosingCore()
    core.rate_hz = float("nan")
    assert run_node("sound", lambda settings, extra: core, ["--no-discovery", "--no-oscquery", "--port", "0"]) == 2
    assert core.closed
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "is not a rate" in err[0]
