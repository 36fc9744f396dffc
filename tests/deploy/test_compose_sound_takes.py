"""compose's sound command keeps one recording per run in ./out (it used to replace the previous run's)."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import soundfile as sf

from tests.deploy.test_compose import compose_config

ROOT = Path(__file__).resolve().parents[2]
TAKE = re.compile(r"batteur-\d{8}-\d{6}(-\d+)?\.wav")


def _sound_command(out: Path) -> list[str]:
    """The sound service's command as compose resolves it, /out translated to ``out`` and kept off the network
    (loopback, any port, no mDNS) so it runs beside other tests."""
    command = [str(a) for a in compose_config()["services"]["sound"]["command"]]
    assert command[0] == "sound"
    command = [str(out) + a[len("/out"):] if a.startswith("/out/") else a for a in command]
    command[command.index("--port") + 1] = "0"
    return [*command, "--no-discovery", "--no-oscquery", "--clock-master", "self", "--channels", "1"]


def _run_once(command: list[str], out: Path, log: Path) -> str:
    """One `docker compose up` / `stop` of the sound service: start it, let it record, SIGTERM; its stderr."""
    before = set(out.iterdir())
    env = {k: v for k, v in os.environ.items() if not k.startswith("BATTEUR_")}
    env["BATTEUR_HOST"] = "127.0.0.1"
    with log.open("w") as err:
        proc = subprocess.Popen([sys.executable, "-m", "batteur", *command], cwd=ROOT, env=env,
                                stdout=subprocess.DEVNULL, stderr=err)
        try:
            deadline = time.monotonic() + 120.0
            while not any(p.stat().st_size > 50_000 for p in set(out.iterdir()) - before if p.is_file()):
                assert proc.poll() is None and time.monotonic() < deadline, log.read_text()
                time.sleep(0.05)
            proc.send_signal(signal.SIGTERM)  # what `docker compose stop` sends (through init)
            assert proc.wait(60) == 0, log.read_text()
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait(60)
    return log.read_text()


def test_two_runs_of_the_compose_sound_service_keep_two_recordings(tmp_path: Path) -> None:
    out = tmp_path / "out"
    out.mkdir()
    command = _sound_command(out)
    assert any(a.endswith("/batteur-{start}.wav") for a in command), command
    logs = [_run_once(command, out, tmp_path / f"run{i}.log") for i in (1, 2)]
    takes = sorted(p.name for p in out.iterdir() if p.suffix == ".wav")
    # was: one batteur.wav, the first run's take replaced by the second's
    assert len(takes) == 2 and all(TAKE.fullmatch(t) for t in takes), sorted(p.name for p in out.iterdir())
    assert sorted(p.name for p in out.iterdir()) == sorted([*takes, *(t + ".json" for t in takes)])  # no part file
    for take in takes:
        assert sf.info(out / take).frames > 10_000
    # each run's log names its own file
    named = [re.findall(r"recording to (\S+) \(in \S+ until the node stops\)", text) for text in logs]
    assert sorted(Path(n[0]).name for n in named if len(n) == 1) == takes, logs
