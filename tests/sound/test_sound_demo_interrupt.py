"""``python -m services.sound.demo``: Ctrl-C while it starts (its modules load for about a second, then the score
is read) ends it with one line and status 130, nothing written; its --help is plain text."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from services.sound.demo import PROG, main

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("delay_s", [0.2, 0.5, 1.0])
def test_ctrl_c_while_starting_is_one_line_and_status_130(tmp_path: Path, delay_s: float) -> None:
    out = tmp_path / "groove.wav"
    # SIGINT at its default: a suite run in the background ignores it, and so would the child
    proc = subprocess.Popen([sys.executable, "-m", "services.sound.demo", "-o", str(out), "--seconds", "1",
                             "--mono"], cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            start_new_session=True, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    time.sleep(delay_s)  # any moment of the start: the assertions hold whichever part it lands in
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=300)
    # was: a KeyboardInterrupt traceback (or "Exception ignored ... KeyboardInterrupt" and the render went on)
    assert "Traceback" not in err and "Exception ignored" not in err, err
    if proc.returncode == 0:  # the machine was quick: it finished before the signal
        assert out.exists()
    else:
        assert proc.returncode == 130, err
        assert err.strip().splitlines()[-1] in (f"{PROG}: interrupted: nothing written",
                                                f"{PROG}: interrupted: {out} not written")
        assert list(tmp_path.iterdir()) == []


def test_ctrl_c_while_reading_the_score_returns_130(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    def interrupted(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr("services.sound.demo.read_score", interrupted)
    try:
        code = main(["-o", str(tmp_path / "groove.wav")])
    except KeyboardInterrupt:  # caught here: pytest would take it for the user's and stop the session
        pytest.fail("Ctrl-C while reading the score escaped main (a traceback)")
    assert code == 130
    assert capsys.readouterr().err == f"{PROG}: interrupted: nothing written\n"
    assert list(tmp_path.iterdir()) == []


def test_help_is_plain_text() -> None:
    run = subprocess.run([sys.executable, "-m", "services.sound.demo", "--help"], cwd=ROOT, capture_output=True,
                         text=True, timeout=120, check=False)
    assert run.returncode == 0 and "SoundCore" in run.stdout and "Impact" in run.stdout
    for markup in ("``", ":class:", ":func:", ":meth:", "`"):
        assert markup not in run.stdout, markup
