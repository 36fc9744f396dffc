"""The clock master answers clock pings within a budget per sender address and per sender host (common/runtime.py,
``PONG_*``): a forged source cannot turn it into a reflector, and a host's other clients keep their pongs while one
of its sockets floods. Unbudgeted, one 65 kB datagram bundling 1259 pings drew 1259 pongs, 91 kB (a pong is 1.5
times its ping), and single pings were answered as fast as they came."""

from __future__ import annotations

import asyncio
import socket
from typing import NamedTuple

import pytest

import common.runtime
from common.config import load_settings
from common.messages import PROTOCOL_VERSION, ClockPing, ClockPong, Health, Hello, OscMessage, decode, encode
from common.messages.codec import encode_bundle
from common.runtime import (
    FAST_PING_SAMPLES,
    PONG_ADDRESS_BURST,
    PONG_ADDRESS_RATE_HZ,
    PONG_HOST_BURST,
    Node,
    PongBudget,
)
from common.stats import DropReason
from tests.null_core import NullCore

pytestmark = pytest.mark.timeout(60)

BUNDLE_BYTES = 60_000
"""A bundle of pings, at most this many bytes (one UDP datagram)."""
SCRIPT_PINGS = 8
"""Pings a client script sends in a row, each after the last one's pong (docs/live-control.md's example)."""


@pytest.fixture
def pongs_never_refill(monkeypatch: pytest.MonkeyPatch) -> None:
    """The bursts only, so how many pings are answered does not depend on how fast the node goes (read when a node
    is made)."""
    monkeypatch.setattr(common.runtime, "PONG_ADDRESS_RATE_HZ", 0.0)
    monkeypatch.setattr(common.runtime, "PONG_HOST_RATE_HZ", 0.0)


def _socket(host: str) -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind((host, 0))
    sock.setblocking(False)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 8 << 20)  # all of an unbudgeted answer fits
    return sock


def _bundle_of_pings(node_id: str) -> tuple[bytes, int]:
    """A datagram bundling as many pings (sequence numbers 0, 1, ...) as fit; and how many."""
    size = 4 + len(encode(ClockPing(node_id=node_id, seq=0, t_send=0.0)))
    count = (BUNDLE_BYTES - 16) // size
    bundle = encode_bundle([ClockPing(node_id=node_id, seq=i, t_send=0.0) for i in range(count)])
    assert len(bundle) <= BUNDLE_BYTES
    return bundle, count


class Answers(NamedTuple):
    pongs: int
    pong_bytes: int
    """The pongs' datagrams' sizes, bytes."""


async def _pongs_until_health(sock: socket.socket) -> Answers:
    """The pongs received on ``sock`` before the first Health (the answer to a Hello sent after the pings: one
    sender's datagrams are handled in order; Hellos have a budget of their own)."""
    loop = asyncio.get_running_loop()
    pongs = size = 0
    while True:
        data = await asyncio.wait_for(loop.sock_recv(sock, 65536), 20.0)
        (message,) = decode(data).messages  # one message a datagram
        if isinstance(message, Health):
            return Answers(pongs, size)
        assert isinstance(message, ClockPong)
        pongs += 1
        size += len(data)


async def _ping_pong(sock: socket.socket, to: tuple[str, int], seq: int) -> OscMessage:
    """One ping and what comes back first."""
    loop = asyncio.get_running_loop()
    await loop.sock_sendto(sock, encode(ClockPing(node_id="script", seq=seq, t_send=float(seq))), to)
    data = await asyncio.wait_for(loop.sock_recv(sock, 65536), 20.0)
    (message,) = decode(data).messages
    return message


async def _node() -> Node:
    node = Node(NullCore(), load_settings({"role": "sound", "discovery": False, "clock_master": "self",  # type: ignore[arg-type]
                                           "oscquery": False}))
    await node.start()
    return node


def _hello(sock: socket.socket) -> bytes:
    return encode(Hello(role="sound", node_id="asker", protocol=PROTOCOL_VERSION, osc_port=sock.getsockname()[1]))


@pytest.mark.usefixtures("pongs_never_refill")
def test_a_bundle_of_pings_from_one_address_is_cut_to_its_budget_and_its_host_keeps_its_pongs() -> None:
    async def main() -> tuple[int, int, Answers, int, list[OscMessage]]:
        node = await _node()
        assert node.endpoint is not None
        to = ("127.0.0.1", node.endpoint.port)
        loop = asyncio.get_running_loop()
        flooder, client = _socket("127.0.0.1"), _socket("127.0.0.1")  # one host, two sockets
        try:
            bundle, count = _bundle_of_pings("forged")
            await loop.sock_sendto(flooder, bundle, to)
            await loop.sock_sendto(flooder, _hello(flooder), to)
            answers = await _pongs_until_health(flooder)
            rate_limited = node.endpoint.stats.dropped[DropReason.RATE_LIMITED]
            script = [await _ping_pong(client, to, seq) for seq in range(SCRIPT_PINGS)]
            return len(bundle), count, answers, rate_limited, script
        finally:
            flooder.close()
            client.close()
            await node.stop()

    sent_bytes, pings, answers, rate_limited, script = asyncio.run(main())
    assert pings > 1000
    assert answers.pongs == PONG_ADDRESS_BURST
    assert answers.pong_bytes < sent_bytes / 10  # no reflector: far fewer bytes back than sent
    assert rate_limited == pings - PONG_ADDRESS_BURST  # the rest counted (Health's dropped_other)
    # another socket of the flooding host: every ping answered
    assert [(type(m), getattr(m, "seq", None)) for m in script] == [(ClockPong, seq) for seq in range(SCRIPT_PINGS)]


@pytest.mark.usefixtures("pongs_never_refill")
def test_a_flood_from_many_ports_of_one_host_is_cut_to_the_host_budget() -> None:
    """Forged sources of one host varying their port: each address has a budget of its own, the host all of them
    together; another host is answered."""
    sockets = int(PONG_HOST_BURST // PONG_ADDRESS_BURST) + 1

    async def main() -> tuple[int, list[Answers], OscMessage]:
        node = await _node()
        assert node.endpoint is not None
        to = ("127.0.0.1", node.endpoint.port)
        loop = asyncio.get_running_loop()
        flooders = [_socket("127.0.0.1") for _ in range(sockets)]
        other = _socket("127.0.0.2")
        try:
            bundle, count = _bundle_of_pings("forged")
            for sock in flooders:
                await loop.sock_sendto(sock, bundle, to)
                await loop.sock_sendto(sock, _hello(sock), to)
            answers = [await _pongs_until_health(sock) for sock in flooders]
            return count, answers, await _ping_pong(other, to, 1)
        finally:
            for sock in [*flooders, other]:
                sock.close()
            await node.stop()

    pings, answers, other = asyncio.run(main())
    assert sockets * PONG_ADDRESS_BURST > PONG_HOST_BURST  # more than the host's, if each socket got its own
    assert all(a.pongs <= PONG_ADDRESS_BURST for a in answers)
    assert sum(a.pongs for a in answers) == PONG_HOST_BURST
    assert isinstance(other, ClockPong) and other.seq == 1


def test_the_budget_keeps_every_pong_of_real_clients_while_one_socket_of_their_host_floods() -> None:
    """The sizing, on a virtual clock with the real budgets: three nodes of a rig and a tool on one machine, all
    pinging fast at once (a master restart: 10 Hz until 8 samples, then 1 Hz), and a script's 8 pings in a row,
    while another socket of that machine sends 1000 pings a second for 10 s: every real ping answered, the flood
    cut to its address's budget."""
    budget = PongBudget()
    host = "10.0.0.5"
    nodes = [f"{host}:{9100 + i}" for i in range(4)]
    pings: list[tuple[float, str]] = [(i / 10, node) for node in nodes for i in range(FAST_PING_SAMPLES)]
    pings += [(FAST_PING_SAMPLES / 10 + i, node) for node in nodes for i in range(10)]
    pings += [(0.05 + i * 0.001, f"{host}:9200") for i in range(SCRIPT_PINGS)]  # a script, 1 ms round trips
    flood = f"{host}:40000"
    pings += [(i / 1000, flood) for i in range(10_000)]
    answered: dict[str, int] = {}
    refused: dict[str, int] = {}
    for t, address in sorted(pings):
        counts = answered if budget.take(host, address, t) else refused
        counts[address] = counts.get(address, 0) + 1
    assert set(refused) == {flood}
    assert answered[flood] <= PONG_ADDRESS_BURST + PONG_ADDRESS_RATE_HZ * 10.0 + 1
