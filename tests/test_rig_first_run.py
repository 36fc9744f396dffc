"""The first run on a fresh install: physics compiles its numba kernels (a walkthrough's, load 13: 140 s, past the
60 s ``--ready-timeout``), and ``batteur rig`` gave up with no hint that the first run compiles nor to raise the
timeout; then physics logged ``stopped cleanly before it listened`` and the rig ``physics did not stop in 4 s;
killing it``, which contradict each other.

Stand-in services (a few lines of Python) say what the real ones say; one test runs the real physics node on a cold
kernel cache (an empty NUMBA_CACHE_DIR) and stops it while it compiles."""

from __future__ import annotations

import asyncio
import io
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from batteur import rig
from common.runtime import stopped_while_starting
from tests.ports import free_ports
from tests.test_rig_inputs import Plan, wait_for_file
from tests.test_rig_ready import StandIn, run_rig

pytestmark = pytest.mark.timeout(180)

REPO = Path(__file__).resolve().parents[1]
COMPILING_PHYSICS = ("import sys, time\n"
                     "print('INFO batteur.physics: compiling the physics kernels (no cache yet: ...)', "
                     "file=sys.stderr, flush=True)\n"
                     "time.sleep(120)\n")
"""A physics stand-in compiling its kernels for two minutes (never answering the rig's Hello)."""


def test_a_physics_compiling_past_the_ready_timeout_is_named_with_what_to_do() -> None:
    physics = free_ports(1)[0]
    ready = rig.ReadyWait(timeout_s=2.0, host="127.0.0.1", epoch=time.time(), play_at_s=1.0)
    code, _, err = run_rig([StandIn("physics", physics, 0.0, COMPILING_PHYSICS)], ready)
    assert code == 1
    said = [line for line in err.splitlines() if line.startswith("batteur rig: error:")]
    assert said == ["batteur rig: error: physics not up within --ready-timeout 2 s of launch (no answer to a Hello); "
                    "stopping the rig. physics was still compiling its kernels (no numba cache yet: the first run "
                    "after an install or an update; cached after, or done ahead by `python3 -m "
                    "services.physics.precompile`): give it longer, e.g. --ready-timeout 240"], err


def test_a_physics_whose_kernels_were_ready_is_not_said_to_compile() -> None:
    physics = free_ports(1)[0]
    ready = rig.ReadyWait(timeout_s=2.0, host="127.0.0.1", epoch=time.time(), play_at_s=1.0)
    compiled = COMPILING_PHYSICS.replace("time.sleep(120)", "print('INFO batteur.physics: physics kernels ready "
                                         "(9.0 s)', file=sys.stderr, flush=True); time.sleep(120)")
    code, _, err = run_rig([StandIn("physics", physics, 0.0, compiled)], ready)
    assert code == 1
    assert "still compiling" not in err
    assert ("stopping the rig. A loaded machine, the first run after an install compiling the physics kernels, may "
            "need longer: e.g. --ready-timeout 240") in err, err


def test_the_rig_copies_what_physics_and_the_nodes_say() -> None:
    """The rig looks for these in its services' output without importing physics (numba) to start it."""
    from services.physics.precompile import COMPILING

    assert rig.SAID["compiling"][0] == COMPILING
    assert rig.SAID["stopping"][0] in stopped_while_starting("physics", "SIGTERM")


SAYS_STOPPING_THEN_HANGS = (
    "import signal, sys, time\n"
    "def on_term(signum, frame):\n"
    f"    print('INFO batteur.runtime: ' + {stopped_while_starting('physics', 'SIGTERM')!r}, file=sys.stderr, "
    "flush=True)\n"
    "    time.sleep(120)\n"  # a loaded machine's exit, longer than the rig's stop timeout
    "signal.signal(signal.SIGTERM, on_term)\n"
    "open(sys.argv[1], 'w').write('started')\n"
    "time.sleep(120)\n")


def _stopped(tmp_path: Path, code: str) -> str:
    """Run a rig of one stand-in physics, stop it once the stand-in runs (stop timeout 0.5 s); its errors."""
    started = tmp_path / "started"
    err = io.StringIO()
    the_rig = rig.Rig([Plan("physics", code, str(started))], stop_timeout_s=0.5, out=io.StringIO(), err=err)

    async def main() -> int:
        task = asyncio.create_task(the_rig.run(None))
        try:
            await asyncio.to_thread(wait_for_file, started)
        finally:
            the_rig.stopping.set()
        return await asyncio.wait_for(task, timeout=60)

    assert asyncio.run(main()) == 1  # killed: not a clean stop
    return err.getvalue()


def test_a_service_that_said_it_was_stopping_but_is_killed_is_told_so(tmp_path: Path) -> None:
    err = _stopped(tmp_path, SAYS_STOPPING_THEN_HANGS)
    lines = err.splitlines()
    node = next(i for i, line in enumerate(lines) if "was asked to stop while starting" in line)
    assert "stopping cleanly before it listened" in lines[node] and "stopped cleanly" not in err, err
    assert ("batteur rig: physics did not exit within --stop-timeout 0.5 s of SIGTERM (it said it was stopping, but "
            "had not exited); killing it") in lines[node + 1:], err


def test_a_service_killed_while_compiling_is_told_so(tmp_path: Path) -> None:
    compiling = ("import signal, sys, time\n"
                 "signal.signal(signal.SIGTERM, signal.SIG_IGN)\n"  # busy in native code: the stop waits
                 "print('INFO batteur.physics: compiling the physics kernels (...)', file=sys.stderr, flush=True)\n"
                 "open(sys.argv[1], 'w').write('started')\n"
                 "time.sleep(120)\n")
    assert ("batteur rig: physics did not exit within --stop-timeout 0.5 s of SIGTERM (it was compiling its kernels, "
            "which it stops only between two); killing it") in _stopped(tmp_path, compiling)


def test_a_physics_node_on_a_cold_kernel_cache_says_it_compiles_and_stops_cleanly_when_asked(tmp_path: Path) -> None:
    """The real node: an empty NUMBA_CACHE_DIR is a fresh install's cache; a SIGTERM while it compiles stops it with
    0 and a log that says it is stopping, not that it stopped."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba"), "PYTHONPATH": str(REPO)}
    node = subprocess.Popen(["taskset", "-c", "0", sys.executable, "-m", "batteur", "physics", "--port", "0",
                             "--no-discovery", "--no-oscquery", "--clock-master", "self"],
                            cwd=tmp_path, env=env, stderr=subprocess.PIPE, text=True)
    assert node.stderr is not None
    log: list[str] = []
    try:
        for line in node.stderr:
            log.append(line)
            if "compiling the physics kernels" in line:
                node.send_signal(signal.SIGTERM)
                break
        _, rest = node.communicate(timeout=120)
    finally:
        if node.poll() is None:
            node.kill()
            node.wait()
    text = "".join(log) + rest
    assert ("compiling the physics kernels (no cache yet: the first run after an install or an update; about 10 s, "
            "minutes on a loaded machine; `python3 -m services.physics.precompile` does it ahead)") in text, text
    assert node.returncode == 0, text
    assert "physics was asked to stop while starting (SIGTERM" in text and "stopping cleanly before it listened" in text


def test_a_warm_cache_is_told_from_a_cold_one(tmp_path: Path) -> None:
    code = "from services.physics.precompile import kernels_cached; print(kernels_cached())"
    cold = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=120,
                          env={**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "empty")})
    assert cold.stdout.strip() == "False", cold.stderr
