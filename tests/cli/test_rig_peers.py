"""How ``batteur rig`` tells its services where the others are.

``batteur rig --host 0.0.0.0`` (the LAN case of docs/deployment.md): the rig gives each service the others as
static peers. A wildcard listen address is no address to send to: a datagram sent to 0.0.0.0 is delivered over
loopback, so the clock master's pongs came back from 127.0.0.1 while the pings went to 0.0.0.0, and every node
dropped them as not from its master ("clock pong not from the clock master"): no node but physics ever synced
its clock. The peers must be the address the replies come from.
"""

from __future__ import annotations

import importlib
import json

import pytest

from batteur.rig import build_parser, plan_rig
from common.peers import parse_static_peer


def _peers(host: str) -> dict[str, dict[str, tuple[str, int]]]:
    opts = build_parser().parse_args(["--host", host, "--no-discovery"])
    peers: dict[str, dict[str, tuple[str, int]]] = {}
    for plan in plan_rig(opts, epoch=0.0):
        specs = [plan.args[i + 1] for i, a in enumerate(plan.args) if a == "--peer"]
        peers[plan.role] = {p.role: p.address for p in map(parse_static_peer, specs)}
    return peers


@pytest.mark.parametrize(("host", "loopback"), [("0.0.0.0", "127.0.0.1"), ("::", "::1")])
def test_a_wildcard_host_gives_loopback_peers(host: str, loopback: str) -> None:
    peers = _peers(host)
    assert peers["sound"]["physics"] == (loopback, 9101)  # the clock master, where its pongs come from
    assert {addr[0] for table in peers.values() for addr in table.values()} == {loopback}


@pytest.mark.parametrize("host", ["127.0.0.1", "192.168.1.10", "::1"])
def test_an_address_host_is_the_peers_address(host: str) -> None:
    peers = _peers(host)
    assert peers["interaction"]["sound"] == (host, 9103)


def test_no_static_peers_and_no_discovery_is_refused_for_several_services() -> None:
    """Neither a peer list nor zeroconf: the services would run side by side without ever finding each other."""
    opts = build_parser().parse_args(["--no-discovery", "--no-static-peers"])
    with pytest.raises(ValueError, match="--no-static-peers"):
        plan_rig(opts, epoch=0.0)
    alone = build_parser().parse_args(["--no-discovery", "--no-static-peers", "--services", "sound"])
    assert [p.role for p in plan_rig(alone, epoch=0.0)] == ["sound"]  # one service has no one to find


def test_the_roles_the_rig_does_not_start_are_given_as_absent(capsys: pytest.CaptureFixture[str]) -> None:
    """``batteur rig --services physics,interaction,sound`` (docs/live-control.md): physics and interaction logged
    "no graphics peer known" once, then once a minute, for a role the rig left out. Each service is told
    (``--absent graphics``, which its parser takes: the settings it would run with have it); the full rig tells
    none, a rig of one service tells it the other three. (A service started by itself, ``batteur physics``, is told
    nothing and warns as before: tests/test_no_peer_warning.py.)"""
    from batteur import cli

    opts = build_parser().parse_args(["--services", "physics,interaction,sound", "--no-discovery"])
    plans = plan_rig(opts, epoch=0.0)
    for plan in plans:
        assert [plan.args[i + 1] for i, a in enumerate(plan.args) if a == "--absent"] == ["graphics"], plan.args
    interaction = next(p for p in plans if p.role == "interaction")
    module = importlib.import_module(cli.COMMANDS["interaction"][0])
    assert module.main([*interaction.args, "--show-settings"]) == 0
    assert json.loads(capsys.readouterr().out)["absent"] == ["graphics"]
    full = plan_rig(build_parser().parse_args(["--no-discovery"]), epoch=0.0)
    assert not [p for p in full if "--absent" in p.args]
    alone = plan_rig(build_parser().parse_args(["--no-discovery", "--services", "sound"]), epoch=0.0)
    assert [a for i, a in enumerate(alone[0].args) if alone[0].args[i - 1] == "--absent"] == [
        "physics", "interaction", "graphics"]


def _absent(*argv: str) -> dict[str, list[str]]:
    plans = plan_rig(build_parser().parse_args(list(argv)), epoch=0.0)
    return {p.role: [p.args[i + 1] for i, a in enumerate(p.args) if a == "--absent"] for p in plans}


def test_a_role_the_rig_may_find_on_another_machine_is_not_absent() -> None:
    """docs/deployment.md's two laptops: ``batteur rig --services physics,interaction,graphics --host 0.0.0.0
    --interfaces 192.168.1.10`` with sound on laptop B, found by discovery. The rig gave each service ``--absent
    sound``, silencing the one line that says discovery did not find it. A role is absent only where no node of it
    can be expected: discovery off, or the service on loopback (a node of it would be on this machine), and no
    static peer of it given."""
    lan = ("--services", "physics,interaction,graphics", "--host", "0.0.0.0")
    assert _absent(*lan, "--interfaces", "192.168.1.10") == {"physics": [], "interaction": [], "graphics": []}
    assert _absent(*lan, "--no-discovery") == {"physics": ["sound"], "interaction": ["sound"], "graphics": ["sound"]}
    here = _absent("--services", "physics,interaction,sound")  # discovery on loopback: this machine's rig
    assert here == {"physics": ["graphics"], "interaction": ["graphics"], "sound": ["graphics"]}
    peered = _absent("--services", "physics,interaction,graphics", "--no-discovery",
                     "--interaction-arg=--peer sound=192.168.1.20:9103")
    assert peered == {"physics": ["sound"], "interaction": [], "graphics": ["sound"]}
