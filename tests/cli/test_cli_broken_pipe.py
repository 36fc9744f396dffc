"""``batteur compare EXERCISE TAKE | head -1`` ended with a BrokenPipeError traceback and exit 1 once ``head`` had
gone: for every batteur command a reader that goes away is a quiet stop, exit 0 (batteur/cli.py)."""

from __future__ import annotations

import socket
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).parents[2]
TAKE = ROOT / "tests" / "data" / "groove_drummer6_s3_1_rock_90_beat_4-4.mid"


def _only_warnings(err: str) -> list[str]:
    """The lines of ``err`` that are not compare's warnings (reading the take: its pitch 58 played as china)."""
    return [line for line in err.splitlines() if not line.startswith("batteur compare: warning: ")]


def test_a_reader_that_went_away_is_a_quiet_stop() -> None:
    # the pipe's read end is closed before the command writes anything: every write of it fails (EPIPE)
    proc = subprocess.Popen([sys.executable, "-m", "batteur", "compare", "demo", str(TAKE)], cwd=ROOT,
                            stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    assert proc.stdout is not None
    proc.stdout.close()
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 0, err.decode()
    assert _only_warnings(err.decode()) == []  # was a BrokenPipeError traceback


def test_a_command_writing_to_a_reader_still_there_keeps_its_status() -> None:
    done = subprocess.run([sys.executable, "-m", "batteur", "compare", "demo", str(ROOT / "no-such-take.mid")],
                          cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert done.returncode == 1 and "no-such-take.mid" in done.stderr


def test_a_socket_reader_that_went_away_is_a_quiet_stop_too() -> None:
    # stdout a socket (a service manager's, inetd's) whose reader closed: it polls POLLHUP, not POLLERR
    ours, theirs = socket.socketpair()
    ours.close()
    with theirs:
        done = subprocess.run([sys.executable, "-m", "batteur", "compare", "demo", str(TAKE)], cwd=ROOT,
                              stdout=theirs, stderr=subprocess.PIPE, timeout=120)
    assert done.returncode == 0, done.stderr.decode()
    assert _only_warnings(done.stderr.decode()) == []


def test_another_broken_pipe_with_stdout_still_read_is_the_command_s_failure() -> None:
    # a command whose own pipe or socket breaks (not stdout): its failure, not a quiet stop
    code = ("import batteur.cli as cli\n"
            "def broken(argv):\n"
            "    print('some output')\n"
            "    raise BrokenPipeError(32, 'Broken pipe')\n"
            "cli.load_command = lambda name: broken\n"
            "raise SystemExit(cli.main(['ls']))\n")
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert done.returncode == 1 and "BrokenPipeError" in done.stderr, done.stderr
    assert done.stdout == "some output\n"
