"""Security defaults: loopback unless told otherwise, LAN only with an allow-list, strangers dropped
and counted, message size and rate limits.

(Handlers and files: tests/test_fuzz_handlers.py; decoders: tests/test_fuzz_decoders.py.)
"""

from __future__ import annotations

import asyncio
import json
import socket
import time

import pytest

from common.config import NodeSettings, SettingsError, load_settings
from common.messages import DropReason, Hello, OscMessage, encode, encode_raw
from common.runtime import Node
from common.transport import UdpEndpoint
from tests.deploy.twohosts import wait_line
from tests.netns import NetnsLab, netns_lab  # noqa: F401  (fixture)
from tests.null_core import NullCore
from tests.waiting import wait_for

pytestmark = pytest.mark.timeout(120)




def test_defaults_keep_a_node_on_loopback() -> None:
    settings = NodeSettings()
    assert settings.host == "127.0.0.1" and settings.interfaces == ["127.0.0.1"]
    assert settings.allow_networks is None  # loopback: only this machine can reach it anyway

    async def main() -> None:
        node = Node(NullCore(), load_settings({"role": "sound", "clock_master": "self", "discovery": False}))
        await node.start()
        assert node.endpoint is not None and node.endpoint.local_address.startswith("127.0.0.1:")
        assert node.oscquery is not None and node.oscquery.host == "127.0.0.1"
        await node.stop()

    asyncio.run(main())


@pytest.mark.parametrize("host", ["0.0.0.0", "::", "192.168.1.20"])
def test_listening_off_loopback_needs_an_allow_list(host: str) -> None:
    with pytest.raises(SettingsError, match="--allow"):
        load_settings({"host": host})
    settings = load_settings({"host": host, "allow": ["192.168.1.0/24"]})
    nets = [str(n) for n in settings.allow_networks or []]
    assert nets == ["192.168.1.0/24", "127.0.0.0/8", "::1/128"]


def test_oversize_and_flooding_sources_are_dropped_and_counted() -> None:
    async def main() -> None:
        endpoint = await UdpEndpoint.open(max_datagram=1024, max_rate=50.0, max_burst=10.0)
        got: list[OscMessage] = []
        endpoint.set_handler(lambda m, s: got.append(m))
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.sendto(encode_raw("/batteur/hello", ["x" * 2000, "n", 1, 2]), ("127.0.0.1", endpoint.port))
            hello = encode(Hello(role="sound", node_id="n", protocol=1, osc_port=1))
            for _ in range(200):  # a burst of 200 from one source: 10 pass at once, the rest is over the rate
                s.sendto(hello, ("127.0.0.1", endpoint.port))
            await wait_for(lambda: endpoint.stats.dropped[DropReason.RATE_LIMITED] + len(got) >= 200)
        stats = endpoint.stats
        assert stats.dropped[DropReason.OVERSIZE] == 1
        assert 10 <= len(got) <= 15  # the burst, plus what the rate refilled meanwhile
        assert stats.dropped[DropReason.RATE_LIMITED] == 200 - len(got)
        endpoint.close()

    asyncio.run(main())


@pytest.mark.slow
def test_a_lan_node_drops_and_counts_packets_from_outside_its_allow_list(netns_lab: NetnsLab) -> None:  # noqa: F811
    lan, stranger_ns = netns_lab.namespace("lan"), netns_lab.namespace("stranger")
    addr, stranger = netns_lab.veth(lan, stranger_ns)
    friend_net = "10.254.0.0/16"  # the allowed LAN is elsewhere: the stranger's 10.x/24 is not in it
    assert not stranger.startswith("10.254.")
    node = lan.python("-m", "batteur", "interaction", "--host", "0.0.0.0", "--port", "9102", "--allow", friend_net,
                      "--no-discovery", "--clock-master", "self", "--interaction-config", "none")
    wait_line(node, lambda s: "listening on" in s and "node" in s, 60)
    hello = encode(Hello(role="x", node_id="stranger", protocol=1, osc_port=9))
    sender = stranger_ns.run(
        "python3", "-c",
        "import socket, sys; s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM); "
        f"[s.sendto(bytes.fromhex('{hello.hex()}'), ('{addr}', 9102)) for _ in range(25)]", check=False)
    assert sender.returncode == 0, sender.stderr
    # the node's health, asked from its own machine (loopback is always allowed)
    deadline = time.monotonic() + 20
    while True:
        out = lan.run("python3", "-m", "batteur", "ls", "--node", "127.0.0.1:9102", "--json", check=False, timeout=30)
        rows = json.loads(out.stdout) if out.stdout.strip().startswith("[") else []
        if rows and rows[0].get("status") in ("ok", "behind") and rows[0].get("dropped", 0) >= 25:  # up and answering
            break
        assert time.monotonic() < deadline, out.stdout + out.stderr
        time.sleep(0.5)
    assert rows[0]["dropped"] == 25 and rows[0]["messages_in"] <= 2  # only batteur ls's own Hello got in
    assert any("not_allowed" in line or "allow-list" in line for line in node.errors), node.errors[-10:]
