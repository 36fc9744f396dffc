"""``batteur ls`` says, per node, how its clock follows the rig clock (a two-laptop rig: is sound on physics'
clock, and how well?). Node processes on loopback, discovery off, static peers; an older node (no ClockStatus)
shows "?"."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from batteur.tools import ls
from common.messages import ClockStatus, Health, encode
from tests.health_answerer import HealthAnswerer
from tests.ports import free_ports
from tests.test_runtime import NODE_SCRIPT
from tests.waiting import until

pytestmark = pytest.mark.timeout(120)

ROOT = Path(__file__).resolve().parents[1]
OLD_HEALTH = Health(node_id="graphics-old", role="graphics", protocol=1, time=12.5, rate_hz=60.0,
                    target_rate_hz=60.0, overruns=0, messages_in=1, messages_out=1, dropped=0, dropped_malformed=0,
                    dropped_unknown=0, dropped_type=0, dropped_range=0, dropped_other=0, late=0, peers=1)


def _nodes(ports: list[int]) -> list[str]:
    return [a for p in ports for a in ("--node", f"127.0.0.1:{p}")]


@pytest.fixture
def rig(tmp_path: Path) -> Iterator[tuple[int, int, int, int, int]]:
    """Node processes of the runtime (discovery and OSCQuery off): a physics node (the clock master), a sound node
    with it as its --peer, a sound node whose --peer physics nobody runs, and an older node's stand-in (answers a
    Hello with a Health only). Their ports, then the one of the physics nobody runs."""
    script = tmp_path / "node.py"
    script.write_text(NODE_SCRIPT.replace('run_node("trivial"', "run_node(sys.argv.pop(1)"))
    env = {k: v for k, v in os.environ.items() if not k.startswith("BATTEUR_")}
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    physics, sound, lonely, nobody = free_ports(4)
    nodes = [("physics", physics, []), ("sound", sound, ["--peer", f"physics=127.0.0.1:{physics}"]),
             ("sound", lonely, ["--peer", f"physics=127.0.0.1:{nobody}"])]
    procs: list[subprocess.Popen[bytes]] = []
    old = HealthAnswerer(encode(OLD_HEALTH))
    try:
        for role, port, peers in nodes:
            log = (tmp_path / f"{role}-{port}.log").open("wb")
            procs.append(subprocess.Popen([sys.executable, str(script), role, "--host", "127.0.0.1", "--port",
                                           str(port), "--no-discovery", "--no-oscquery", *peers], cwd=ROOT, env=env,
                                          stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=log))
            log.close()
        yield physics, sound, lonely, old.port, nobody
    finally:
        old.close()
        for proc in procs:
            proc.terminate()
        for proc in procs:
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()


def test_ls_shows_each_nodes_clock(rig: tuple[int, int, int, int, int],
                                   capsys: pytest.CaptureFixture[str]) -> None:
    physics, sound, lonely, old, nobody = rig
    ports = [physics, sound, lonely, old]
    rows: dict[int, dict[str, object]] = {}

    def sound_synced() -> bool:
        nonlocal rows
        code = ls.main([*_nodes(ports), "--timeout", "5", "--json"])
        rows = {int(str(r["address"]).rsplit(":", 1)[1]): r for r in json.loads(capsys.readouterr().out)}
        return code == 0 and str(rows[sound]["clock"]).startswith("synced")

    assert until(sound_synced, timeout_s=60, poll_s=0.2), rows
    assert rows[physics]["clock"] == "master"
    status = rows[sound]["clock_status"]
    assert isinstance(status, dict) and status["synced"] == 1
    assert status["master"] == f"static:physics:127.0.0.1:{physics}"
    # the text is the status's own figures, in milliseconds
    assert rows[sound]["clock"] == ls.clock_text(ClockStatus.model_validate(status))
    assert f"+/- {status['uncertainty_s'] * 1e3:.2f} ms, rtt {status['round_trip_s'] * 1e3:.2f} ms" in \
        str(rows[sound]["clock"])
    assert rows[lonely]["clock"] == f"not synced (no pong from static:physics:127.0.0.1:{nobody})"
    # an older node answers with its Health only: listed as ok, its clock unknown
    assert rows[old]["status"] == "ok" and rows[old]["clock"] == "?" and rows[old]["clock_status"] is None

    # the table has the column
    assert ls.main([*_nodes(ports), "--timeout", "5"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].endswith(" clock")
    by_port = {next(p for p in ports if f"127.0.0.1:{p} " in line): line for line in lines[1:]}
    assert by_port[physics].endswith(" master") and by_port[old].endswith(" ?")
    assert " synced +/- " in by_port[sound] and " not synced (no pong from " in by_port[lonely]


def test_clock_text_says_each_state() -> None:
    def status(**changes: object) -> ClockStatus:
        fields: dict[str, object] = dict(node_id="sound-1", synced=1, offset_s=10.0, uncertainty_s=0.000412,
                                         round_trip_s=0.00123, samples=12, rejected=0, outliers=0, steps=0,
                                         foreign_pongs=0, master="physics-1")
        return ClockStatus.model_validate({**fields, **changes})

    assert ls.clock_text(None) == "?"
    assert ls.clock_text(status(node_id="physics-1")) == "master"
    assert ls.clock_text(status()) == "synced +/- 0.41 ms, rtt 1.23 ms"
    assert ls.clock_text(status(steps=2)) == "synced +/- 0.41 ms, rtt 1.23 ms, 2 steps"
    assert ls.clock_text(status(uncertainty_s=-1.0, round_trip_s=-1.0, samples=0, master="physics-2")) == \
        "synced, no estimate yet from physics-2"
    unsynced = dict(synced=0, offset_s=0.0, uncertainty_s=-1.0, round_trip_s=-1.0, samples=0)
    assert ls.clock_text(status(**unsynced)) == "not synced (no pong from physics-1)"
    assert ls.clock_text(status(**unsynced, rejected=3)) == "not synced (no pong from physics-1, 3 pongs refused)"
    assert ls.clock_text(status(**unsynced, master="")) == "not synced (no clock master found)"
