"""``batteur compare EXERCISE TAKE | head -1`` ended with a BrokenPipeError traceback and exit 1 once ``head`` had
gone: for every batteur command a reader that goes away is a quiet stop, exit 0 (batteur/cli.py)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).parents[2]
TAKE = ROOT / "tests" / "data" / "groove_drummer6_s3_1_rock_90_beat_4-4.mid"


def test_a_reader_that_went_away_is_a_quiet_stop() -> None:
    # the pipe's read end is closed before the command writes anything: every write of it fails (EPIPE)
    proc = subprocess.Popen([sys.executable, "-m", "batteur", "compare", "demo", str(TAKE)], cwd=ROOT,
                            stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    assert proc.stdout is not None
    proc.stdout.close()
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 0, err.decode()
    assert err.decode() == ""  # was a BrokenPipeError traceback


def test_a_command_writing_to_a_reader_still_there_keeps_its_status() -> None:
    done = subprocess.run([sys.executable, "-m", "batteur", "compare", "demo", str(ROOT / "no-such-take.mid")],
                          cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert done.returncode == 1 and "no-such-take.mid" in done.stderr
