"""``batteur rig`` stops whatever its services leave behind: a grandchild (a planning process, a resource
tracker) that outlives its service and holds the rig's output pipe kept the rig waiting for good, deaf to Ctrl-C.

Stand-in services (a few lines of Python, as in test_rig_inputs) play the services.
"""

from __future__ import annotations

import asyncio
import io
import os
import signal
import sys
from pathlib import Path

import pytest

from batteur import rig
from tests.test_rig_inputs import Plan, running, wait_for_file

GRANDCHILD = ("import os, signal, sys, time\n"
              "if sys.argv[2] == 'own-session':\n"
              "    os.setsid()\n"
              "signal.signal(signal.SIGTERM, signal.SIG_IGN)\n"  # as a resource tracker does
              "open(sys.argv[1], 'w').write(str(os.getpid()))\n"
              "time.sleep(120)\n")
"""A grandchild that ignores SIGTERM and holds the rig's output pipe (inherited) for two minutes."""
LEAVES_A_GRANDCHILD = ("import subprocess, sys, time\n"
                       f"subprocess.Popen([sys.executable, '-c', {GRANDCHILD!r}, sys.argv[1], sys.argv[2]])\n"
                       "time.sleep(120)\n")
"""A service that starts the grandchild and ends on SIGTERM without stopping it."""


def run_then_stop(the_rig: rig.Rig, pid_file: Path) -> int:
    """Run ``the_rig``, stop it once ``pid_file`` exists (its grandchild runs); its exit status, within 60 s (before
    the fix: 120 s, the grandchild's whole life)."""

    async def main() -> int:
        task = asyncio.create_task(the_rig.run(None))
        try:
            await asyncio.to_thread(wait_for_file, pid_file)
        finally:
            the_rig.stopping.set()
        return await asyncio.wait_for(task, timeout=60)

    return asyncio.run(main())


def run_rig_until_grandchild(tmp_path: Path, session: str) -> tuple[rig.Rig, int]:
    """Run a rig of one service leaving a grandchild (``session``: 'own-session' or 'same-group'), stopped once
    the grandchild runs; the rig and the grandchild's pid."""
    pid_file = tmp_path / "grandchild.pid"
    the_rig = rig.Rig([Plan("physics", LEAVES_A_GRANDCHILD, str(pid_file), session)], stop_timeout_s=20,
                      out=io.StringIO(), err=io.StringIO())

    assert run_then_stop(the_rig, pid_file) == 0
    return the_rig, int(pid_file.read_text())


def test_the_rig_leaves_no_grandchild_of_a_service_behind(tmp_path: Path) -> None:
    _, grandchild = run_rig_until_grandchild(tmp_path, "same-group")
    try:
        assert not running(grandchild)
    finally:
        if running(grandchild):
            os.kill(grandchild, signal.SIGKILL)


def test_a_grandchild_in_its_own_session_does_not_keep_the_rig_running(tmp_path: Path) -> None:
    # out of the service's process group the rig cannot find it; it must not wait for its end
    the_rig, grandchild = run_rig_until_grandchild(tmp_path, "own-session")
    try:
        assert all(proc.returncode is not None for proc in the_rig.procs.values())
    finally:
        if running(grandchild):
            os.kill(grandchild, signal.SIGKILL)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="process groups as on Linux")
def test_a_service_killed_for_not_stopping_takes_its_children_with_it(tmp_path: Path) -> None:
    pid_file = tmp_path / "grandchild.pid"
    stubborn = ("import signal, subprocess, sys, time\n"
                f"subprocess.Popen([sys.executable, '-c', {GRANDCHILD!r}, sys.argv[1], 'same-group'])\n"
                "signal.signal(signal.SIGTERM, signal.SIG_IGN)\n"
                "time.sleep(120)\n")
    err = io.StringIO()
    the_rig = rig.Rig([Plan("physics", stubborn, str(pid_file))], stop_timeout_s=0.5, out=io.StringIO(), err=err)

    assert run_then_stop(the_rig, pid_file) == 1
    grandchild = int(pid_file.read_text())
    try:
        assert "physics did not exit within --stop-timeout 0.5 s of SIGTERM; killing it" in err.getvalue()
        assert not running(grandchild)
    finally:
        if running(grandchild):
            os.kill(grandchild, signal.SIGKILL)


def test_a_grandchild_gets_sigterm_first_to_clean_up(tmp_path: Path) -> None:
    # a resource tracker removes the semaphores of a killed service once the planning processes are gone; SIGKILL
    # straight away would leave them behind, so what outlives a service is asked to stop before it is killed
    pid_file, cleaned = tmp_path / "grandchild.pid", tmp_path / "cleaned"
    tidy = ("import os, signal, sys, time\n"
            "def clean(*_):\n"
            "    open(sys.argv[2], 'w').write('yes'); sys.exit(0)\n"
            "signal.signal(signal.SIGTERM, clean)\n"
            "open(sys.argv[1], 'w').write(str(os.getpid()))\n"
            "time.sleep(120)\n")
    service = ("import subprocess, sys, time\n"
               f"subprocess.Popen([sys.executable, '-c', {tidy!r}, sys.argv[1], sys.argv[2]])\n"
               "time.sleep(120)\n")
    the_rig = rig.Rig([Plan("physics", service, str(pid_file), str(cleaned))], stop_timeout_s=20,
                      out=io.StringIO(), err=io.StringIO())

    assert run_then_stop(the_rig, pid_file) == 0
    grandchild = int(pid_file.read_text())
    try:
        assert cleaned.exists() and not running(grandchild)
    finally:
        if running(grandchild):
            os.kill(grandchild, signal.SIGKILL)
