"""``python -m common.score FILE | head -1`` ended with a BrokenPipeError traceback once ``head`` had gone: a reader
that goes away is a quiet stop, exit 0, as for the batteur tools (``run_tool``)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

SCORE = Path(__file__).parents[1] / "render" / "short_groove.txt"
ROOT = Path(__file__).parents[2]


def test_a_reader_that_went_away_is_a_quiet_stop() -> None:
    # the pipe's read end is closed before the command writes anything: every write of it fails (EPIPE)
    proc = subprocess.Popen([sys.executable, "-m", "common.score", str(SCORE), "--plan"], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert proc.stdout is not None
    proc.stdout.close()
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 0, err.decode()
    assert err.decode() == ""  # was a BrokenPipeError traceback
