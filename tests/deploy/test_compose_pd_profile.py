"""compose's ``pd`` profile as docs/deployment.md gives it: ``BATTEUR_PEERS=sound=pd-sound:9103 docker compose
--profile pd up`` sends interaction's impacts to the Pd client, by its service name, across the compose network;
``docker compose exec interaction batteur send --raw /pd/record 1 --to pd-sound:9103`` records a take in ./out.

Interaction and pd-sound run their exact compose command lines and environments in namespaces on one bridge
(tests/deploy/test_compose.py's network: eth0, /etc/hosts naming the services); a third namespace stands for
physics and sends interaction the contacts of three strikes.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import pytest

from common.messages import encode
from tests.deploy.pdrun import pd_binary, three_strikes
from tests.deploy.test_compose import ROOT, _compose_network, _entrypoint, _remove_hosts, _translate, compose_config
from tests.netns import NetnsLab, NsProcess, netns_lab  # noqa: F401  (fixture)

SEND_CONTACTS = """
import json, socket, sys, time
contacts = json.loads(sys.argv[1])
with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
    start = time.monotonic()
    for at, data in contacts:
        time.sleep(max(0.0, start + at - time.monotonic()))
        s.sendto(bytes.fromhex(data), ("interaction", 9102))
"""
"""Run in the physics namespace: send each (time s, datagram hex) to interaction by its service name."""


def _contacts() -> list[tuple[float, str]]:
    return [(c.time, encode(c).hex()) for c in three_strikes()]


def _wait_log(proc: NsProcess, needle: str, timeout: float = 60.0) -> None:
    deadline = time.monotonic() + timeout
    while not any(needle in line for line in proc.errors):
        assert proc.popen.poll() is None and time.monotonic() < deadline, proc.describe(f"no {needle!r}")
        time.sleep(0.05)


@pytest.mark.slow
@pytest.mark.timeout(180)
def test_the_pd_profile_sends_interactions_impacts_to_pd_sound(netns_lab: NetnsLab, tmp_path: Path) -> None:  # noqa: F811
    pd = pd_binary()
    if pd is None:
        pytest.skip("Pure Data is not installed (Debian: apt-get install puredata-core)")
    services = compose_config({"BATTEUR_PEERS": "sound=pd-sound:9103"}, profiles=("pd",))["services"]
    namespaces, _ = _compose_network(netns_lab, ["physics", "interaction", "pd-sound"])
    volumes = {"/out": tmp_path / "out", "/config": tmp_path / "config"}
    for folder in volumes.values():
        folder.mkdir()
    try:
        service = services["interaction"]
        env = {k: _translate(str(v), volumes) for k, v in service["environment"].items()}
        env["HOME"] = str(tmp_path)
        interaction = namespaces["interaction"].python(
            "-m", "batteur", *[_translate(str(a), volumes) for a in service["command"]], env=env)
        # the take folder is inside a -send message ("sc-dir symbol /out")
        command = [" ".join(_translate(w, volumes) for w in str(a).split(" ")) for a in services["pd-sound"]["command"]]
        entry = _entrypoint(ROOT / "docker" / "Dockerfile.pd")
        client = namespaces["pd-sound"].popen(pd, *entry[1:], *command[:-1], str(ROOT / "pd" / command[-1]))
        _wait_log(client, "batteur-listen: listen 9103 0.0.0.0")
        _wait_log(interaction, "core starts")  # no physics node: it starts on its own clock after 3 s
        sent = namespaces["physics"].run(sys.executable, "-c", SEND_CONTACTS, json.dumps(_contacts()), timeout=60)
        assert sent.returncode == 0, sent.stderr
        deadline = time.monotonic() + 30
        while len([line for line in client.errors if line.startswith("batteur-impact:")]) < 3:
            assert time.monotonic() < deadline, client.describe("fewer than 3 strikes played")
            time.sleep(0.05)
        peer = "peer sound static:sound:pd-sound:9103 at pd-sound"
        assert any(peer in line for line in interaction.errors), interaction.errors
        played = [line.split()[2:] for line in client.errors if line.startswith("batteur-impact:")]
        # four copies of each impact: each played once, at its rig time
        assert [p[0] for p in played] == ["snare", "floortom", "crash"], client.errors
        assert [float(p[1]) + float(p[2]) for p in played] == pytest.approx([0.2, 0.5, 0.8], abs=0.0015)
        assert not any(line.startswith("batteur-bad") for line in client.errors), client.errors
        # a take, asked for from another container as the docs say
        for address in ("/pd/record", "/pd/stop"):
            args = ["1"] if address == "/pd/record" else []
            asked = namespaces["interaction"].run(sys.executable, "-m", "batteur", "send", "--raw", address, *args,
                                                  "--to", "pd-sound:9103", timeout=60)
            assert asked.returncode == 0, asked.stderr
            _wait_log(client, "batteur-stop" if address == "/pd/stop" else "batteur-record")
        assert [p.name for p in volumes["/out"].iterdir()] == ["take-1.wav"]
    finally:
        _remove_hosts(namespaces)
