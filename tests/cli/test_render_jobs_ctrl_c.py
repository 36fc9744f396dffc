"""Ctrl-C in a terminal during ``batteur render --jobs N``: one line and status 130, no worker tracebacks.

A terminal's Ctrl-C sends SIGINT to the whole process group, so the worker processes get it too. A worker
still importing (PyBullet, numba, scipy: seconds) or waiting for its next segment printed a
``KeyboardInterrupt`` traceback of dozens of lines under the render's own message (and one that died before
reading its first segment could leave the render hung at exit). The parent stops the workers itself (the
segments' stop event), so SIGINT does not reach them.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SIGINT_BIT = 1 << (signal.SIGINT - 1)


def _children(pid: int) -> list[int]:
    try:
        text = Path(f"/proc/{pid}/task/{pid}/children").read_text()
    except OSError:
        return []
    return [int(p) for p in text.split()]


def _status_mask(pid: int, field: str) -> int:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1], 16)
    raise AssertionError(f"no {field} in /proc/{pid}/status")


def _has_pybullet(pid: int) -> bool:
    """A segment worker: it has unpickled its first segment (batteur.render, hence PyBullet, is loaded)."""
    try:
        return "pybullet" in Path(f"/proc/{pid}/maps").read_text()
    except OSError:
        return False


@pytest.mark.skipif(not Path("/proc/self/task").exists(), reason="needs Linux /proc")
def test_ctrl_c_to_the_process_group_prints_no_worker_traceback(tmp_path: Path) -> None:
    score = tmp_path / "rock.txt"
    bar = "HH |x.x.x.x.|\nSN |....X...|\nBD |x.......|"
    score.write_text("tempo 100\nmeter 4/4\n" + "\n\n".join([bar] * 60))  # 144 s: never done before the Ctrl-C
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "batteur", "render", str(score), "-o", str(out), "--quiet",
                             "--jobs", "2", "--segment", "4"], cwd=ROOT, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)  # its own process group, as a shell gives a command
    try:
        workers: list[int] = []
        deadline = time.monotonic() + 240  # a bound on the wait, not a measured figure
        while not workers and proc.poll() is None and time.monotonic() < deadline:
            workers = [c for c in _children(proc.pid) if _has_pybullet(c)]
            time.sleep(0.05)
        assert workers, "no segment worker came up"
        # a worker must not turn the terminal's Ctrl-C into its own KeyboardInterrupt (nor die of it)
        assert (_status_mask(workers[0], "SigIgn") | _status_mask(workers[0], "SigBlk")) & SIGINT_BIT
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 130
    assert "Traceback" not in err and "KeyboardInterrupt" not in err
    assert f"interrupted; nothing written to {out}" in err
    assert not out.exists()
