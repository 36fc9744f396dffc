"""SIGTERM (``timeout``, systemd, a render farm's scheduler, ``kill``) during a render: one line, exit status 143
(128 + SIGTERM, as a shell reports it), nothing left in DIR, as after a Ctrl-C.

Until 8 Dec SIGTERM's default action ended the process at once: exit 143 from the shell, nothing on stderr, and DIR
held the staging folder ``.render-*`` with a partial performance.wav, ``performance.bvh.motion`` and
``impacts.csv.rows``. ``batteur evaluate`` renders, and is stopped the same way. With ``--jobs`` the SIGTERM may
reach the parent alone (``timeout``, ``kill PID``) or every process (systemd's control group, ``kill -- -PGID``).

Each render runs as a shell runs a command, in its own process group; the signal is sent once the staging folder
exists (the simulation has started).
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
WAIT_S = 240.0
"""A bound on each wait (the staging folder, the exit), not a measured figure: the machine may be loaded."""
LONG = "tempo 100\nmeter 4/4\n" + "\n\n".join(["HH |x.x.x.x.|\nSN |....X...|\nBD |x.......|"] * 60)
"""144 s of music: never done before the signal."""


def _terminated(command: list[str], tmp_path: Path, out: Path, group: bool = False,
                settle_s: float = 0.0) -> tuple[int, str]:
    """Run ``batteur COMMAND``, send SIGTERM once ``out`` holds a staging folder (``settle_s`` later), to the
    process (``group``: to its whole process group); its exit status and stderr."""
    err_path = tmp_path / "stderr.txt"
    with err_path.open("w") as err:
        proc = subprocess.Popen([sys.executable, "-m", "batteur", *command], cwd=ROOT, stdin=subprocess.DEVNULL,
                                stdout=subprocess.DEVNULL, stderr=err, start_new_session=True)
    try:
        deadline = time.monotonic() + WAIT_S
        while proc.poll() is None and time.monotonic() < deadline and not list(out.rglob(".render-*")):
            time.sleep(0.05)
        assert proc.poll() is None and list(out.rglob(".render-*")), err_path.read_text()
        time.sleep(settle_s)
        if group:
            os.killpg(proc.pid, signal.SIGTERM)
        else:
            proc.send_signal(signal.SIGTERM)
        proc.wait(WAIT_S)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    return proc.returncode, err_path.read_text()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="signals and process groups as on Linux")
@pytest.mark.timeout(600)
def test_sigterm_stops_a_render_in_one_line_leaving_nothing(tmp_path: Path) -> None:
    score = tmp_path / "rock.txt"
    score.write_text(LONG)
    out = tmp_path / "out"
    out.mkdir()
    (out / "mine.txt").write_text("a file of the user's\n")  # DIR existed before: only the render's files go
    status, err = _terminated(["render", str(score), "-o", str(out), "--quiet"], tmp_path, out)
    assert status == 143, err
    assert "Traceback" not in err
    assert err.strip().splitlines() == [f"batteur render: terminated (SIGTERM); nothing written to {out}"]
    assert sorted(p.name for p in out.iterdir()) == ["mine.txt"]  # no .render-* left behind


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="signals and process groups as on Linux")
@pytest.mark.timeout(600)
def test_sigterm_stops_evaluate_and_its_render(tmp_path: Path) -> None:
    score = tmp_path / "rock.txt"
    score.write_text(LONG)
    renders = tmp_path / "renders"
    status, err = _terminated(["evaluate", str(score), "--renders", str(renders), "--quiet"], tmp_path, renders)
    assert status == 143, err
    assert "Traceback" not in err
    assert err.strip().splitlines()[-1] == "batteur evaluate: terminated (SIGTERM)"
    assert not list(tmp_path.rglob(".render-*"))


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="signals and process groups as on Linux")
@pytest.mark.timeout(900)
@pytest.mark.parametrize("group", [False, True], ids=["parent", "every-process"])
def test_sigterm_stops_a_segmented_render(tmp_path: Path, group: bool) -> None:
    """``parent``: as ``timeout`` sends it; ``every-process``: as systemd does (the workers get it too). Sent 3 s
    after the staging folder appears: the workers are simulating, or starting."""
    score = tmp_path / "rock.txt"
    score.write_text(LONG)
    out = tmp_path / "out"
    status, err = _terminated(["render", str(score), "-o", str(out), "--quiet", "--jobs", "2", "--segment", "4"],
                              tmp_path, out, group=group, settle_s=3.0)
    assert status == 143, err
    assert "Traceback" not in err
    said = [line for line in err.splitlines() if line.strip()]
    assert said == [f"batteur render: terminated (SIGTERM); nothing written to {out}"]
    assert not out.exists()
