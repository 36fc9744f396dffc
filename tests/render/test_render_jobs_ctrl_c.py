"""Ctrl-C on a terminal during ``batteur render --jobs N``: one line, exit status 130, nothing written.

A terminal's Ctrl-C sends SIGINT to the whole foreground process group, so the segment workers got it too:
each printed a ``KeyboardInterrupt`` traceback (dozens of lines, from wherever it was: importing, simulating,
waiting for its next segment) under the render's own message. The workers now ignore SIGINT from their start
(the parent stops them through the segments' stop event), and the parent acts on a Ctrl-C only between its
own steps, never halfway through talking to a worker.

The render runs as a shell runs a command: in its own process group (``start_new_session``), its stderr a
terminal (a pty, so the progress bar is drawn), and the SIGINT goes to the whole group (``os.killpg``).
"""

from __future__ import annotations

import os
import pty
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.render.terminal import read_terminal

ROOT = Path(__file__).resolve().parents[2]
BAR = re.compile(r"rendering rock\.txt \[[# ]*\]\s+\d+% ([0-9.]+) s")
"""The render's progress bar on the terminal; its group: rig seconds simulated (all segments, scaled)."""
BARS = ("reading ", "planning ", "rendering ")
"""The starts of the lines on stderr that are not messages: the progress bars."""
WAIT_S = 240.0
"""A bound on each wait (the bar, the exit), not a measured figure: the machine may be loaded."""


def _group_gone(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return True
    return False


@pytest.mark.slow
@pytest.mark.timeout(600)
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="a pty and process groups as on Linux")
@pytest.mark.parametrize("when", ["starting", "simulating"])
def test_ctrl_c_to_the_process_group_stops_a_segmented_render_in_one_line(tmp_path: Path, when: str) -> None:
    """``starting``: the Ctrl-C as soon as the bar is drawn (the workers are being started or import);
    ``simulating``: once the segments have simulated some of the piece."""
    score = tmp_path / "rock.txt"
    bar = "HH |x.x.x.x.|\nSN |....X...|\nBD |x.......|"
    score.write_text("tempo 100\nmeter 4/4\n" + "\n\n".join([bar] * 60))  # 144 s: never done before the Ctrl-C
    out = tmp_path / "out"
    terminal, stderr = pty.openpty()
    proc = subprocess.Popen([sys.executable, "-m", "batteur", "render", str(score), "-o", str(out), "--jobs", "2",
                             "--segment", "4"], cwd=ROOT, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                            stderr=stderr, start_new_session=True)  # its own process group, as a shell gives it
    os.close(stderr)
    shown = ""
    try:
        deadline = time.monotonic() + WAIT_S
        while proc.poll() is None and time.monotonic() < deadline:
            shown += read_terminal(terminal, 0.1)
            done = [float(s) for s in BAR.findall(shown)]
            if done and (when == "starting" or max(done) > 0):
                break
        assert proc.poll() is None and BAR.search(shown), shown[-2000:]
        os.killpg(proc.pid, signal.SIGINT)
        deadline = time.monotonic() + WAIT_S
        while proc.poll() is None and time.monotonic() < deadline:
            shown += read_terminal(terminal, 0.1)
        while chunk := read_terminal(terminal, 0.5):  # what was written just before the exit
            shown += chunk
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
        os.close(terminal)
    lines = [line.split("\r")[-1] for line in shown.replace("\r\n", "\n").split("\n")]
    said = [line for line in lines if line.strip() and not line.startswith(BARS)]  # what is not a progress bar
    assert proc.returncode == 130, said
    assert "Traceback" not in shown and "KeyboardInterrupt" not in shown, said
    assert said == [f"batteur render: interrupted; nothing written to {out}"]
    assert not out.exists() and not list(tmp_path.rglob(".render-*"))
    deadline = time.monotonic() + WAIT_S  # the workers (and multiprocessing's helpers) are gone with it
    while not _group_gone(proc.pid) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert _group_gone(proc.pid)
