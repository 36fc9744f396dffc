"""The UDP transport against an unlucky network: slow or failing name lookups, bad destinations,
closed ports, many destinations, hostile bundles (loopback only)."""

from __future__ import annotations

import asyncio
import socket
import struct
import threading
import tracemalloc
from collections.abc import Coroutine
from typing import Any

import pytest

from common.messages import DropReason, Hello, OscMessage, encode
from common.peers import Peer, PeerTable
from common.transport import UdpEndpoint
from tests.waiting import wait_for

pytestmark = pytest.mark.timeout(60)

GetAddrInfo = Any


def run(coro: Coroutine[Any, Any, Any]) -> Any:
    return asyncio.run(coro)


def hello(i: int) -> Hello:
    return Hello(role="physics", node_id="n", protocol=1, osc_port=i)


def ports(got: list[tuple[OscMessage, str]]) -> list[int]:
    return [m.osc_port for m, _ in got]  # type: ignore[attr-defined]


class SlowDns:
    """A ``getaddrinfo`` for names that waits until released (a DNS server that takes its time).

    Records the thread each lookup ran on; on the event loop's thread it would wait forever, so it
    gives up after 5 s and fails instead.
    """

    def __init__(self, real: GetAddrInfo, answers: dict[str, str]) -> None:
        self.real = real
        self.answers = answers
        self.release = threading.Event()
        self.threads: list[int] = []
        self.fail = False

    def __call__(self, host: Any, *args: Any, **kwargs: Any) -> Any:
        if host not in self.answers:
            return self.real(host, *args, **kwargs)
        self.threads.append(threading.get_ident())
        if not self.release.wait(5.0) or self.fail:
            raise socket.gaierror(socket.EAI_AGAIN, "Temporary failure in name resolution")
        return [(socket.AF_INET, socket.SOCK_DGRAM, 17, "", (self.answers[host], 0))]


class Clock:
    t = 1000.0

    def __call__(self) -> float:
        return self.t


def test_a_slow_name_lookup_does_not_block_the_loop_and_messages_wait_for_it(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    dns = SlowDns(socket.getaddrinfo, {"sound.lan": "127.0.0.1"})
    monkeypatch.setattr(socket, "getaddrinfo", dns)

    async def main() -> None:
        a = await UdpEndpoint.open()
        b = await UdpEndpoint.open()
        got: list[tuple[OscMessage, str]] = []
        b.set_handler(lambda m, s: got.append((m, s)))
        loop_thread = threading.get_ident()
        for i in range(3):
            a.send(hello(i), f"sound.lan:{b.port}")  # returns at once: the lookup runs elsewhere
        a.send(hello(9), b.local_address)  # numeric: not held up by the lookup
        await wait_for(lambda: len(got) >= 1)
        assert ports(got) == [9]
        dns.release.set()
        await wait_for(lambda: len(got) >= 4)
        assert ports(got) == [9, 0, 1, 2]  # in order, none lost
        assert dns.threads and loop_thread not in dns.threads
        assert a.stats.messages_out == 4 and a.unroutable == 0
        a.close()
        b.close()

    run(main())


def test_a_name_is_refreshed_in_the_background_while_its_address_is_used(monkeypatch: pytest.MonkeyPatch) -> None:
    dns = SlowDns(socket.getaddrinfo, {"sound.lan": "127.0.0.1"})
    dns.release.set()
    monkeypatch.setattr(socket, "getaddrinfo", dns)
    clock = Clock()

    async def main() -> None:
        a = await UdpEndpoint.open(clock=clock)
        b = await UdpEndpoint.open()
        got: list[tuple[OscMessage, str]] = []
        b.set_handler(lambda m, s: got.append((m, s)))
        a.send(hello(0), f"sound.lan:{b.port}")
        await wait_for(lambda: len(got) >= 1)
        loop_thread = threading.get_ident()
        dns.release.clear()  # the DNS server is slow now
        clock.t += 31.0  # the cached address is stale
        a.send(hello(1), f"sound.lan:{b.port}")  # sent at once with the old address
        assert a.stats.messages_out == 2
        await wait_for(lambda: len(got) >= 2)
        assert len(dns.threads) == 2 and loop_thread not in dns.threads
        dns.release.set()
        a.close()
        b.close()

    run(main())


def test_a_failed_refresh_keeps_the_last_address(monkeypatch: pytest.MonkeyPatch) -> None:
    """A DNS hiccup 30 s into a show must not silence a peer that is still there."""
    dns = SlowDns(socket.getaddrinfo, {"sound.lan": "127.0.0.1"})
    dns.release.set()
    monkeypatch.setattr(socket, "getaddrinfo", dns)
    clock = Clock()

    async def main() -> None:
        a = await UdpEndpoint.open(clock=clock)
        b = await UdpEndpoint.open()
        got: list[tuple[OscMessage, str]] = []
        b.set_handler(lambda m, s: got.append((m, s)))
        a.send(hello(0), f"sound.lan:{b.port}")
        await wait_for(lambda: len(got) == 1)
        dns.fail = True
        clock.t += 31.0
        a.send(hello(1), f"sound.lan:{b.port}")
        await wait_for(lambda: len(dns.threads) == 2 and a._names["sound.lan"].task is None)  # refresh failed
        a.send(hello(2), f"sound.lan:{b.port}")
        await wait_for(lambda: len(got) == 3)
        assert a.unroutable == 0
        a.close()
        b.close()

    run(main())


def test_an_unresolvable_name_is_counted_and_retried_later(monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[str] = []

    real = socket.getaddrinfo

    def no_dns(host: Any, *args: Any, **kwargs: Any) -> Any:
        if host != "nowhere.invalid":
            return real(host, *args, **kwargs)
        calls.append(host)
        raise socket.gaierror(socket.EAI_NONAME, "Name or service not known")

    monkeypatch.setattr(socket, "getaddrinfo", no_dns)
    clock = Clock()

    async def main() -> None:
        a = await UdpEndpoint.open(clock=clock)
        b = await UdpEndpoint.open()
        got: list[tuple[OscMessage, str]] = []
        b.set_handler(lambda m, s: got.append((m, s)))
        a.send(hello(0), "nowhere.invalid:9000")
        await wait_for(lambda: a.unroutable == 1)
        for i in range(100):  # the failure is remembered: no lookup per send
            a.send(hello(i), "nowhere.invalid:9000")
        assert a.unroutable == 101 and len(calls) == 1
        a.send(hello(7), b.local_address)
        await wait_for(lambda: len(got) == 1)
        clock.t += 10.0  # tried again after a while
        a.send(hello(1), "nowhere.invalid:9000")  # still failing fast while it is looked up again
        assert a.unroutable == 102
        await wait_for(lambda: len(calls) == 2)
        a.close()
        b.close()

    run(main())


@pytest.mark.parametrize("target", [("127.0.0.1", 70000), ("127.0.0.1", -1), ("127.0.0.1", 0), ("", 9000)])
def test_a_bad_destination_is_counted_and_the_endpoint_keeps_working(target: tuple[str, int]) -> None:
    """asyncio closes a datagram transport for good on a port out of range: the node went deaf and mute."""

    async def main() -> None:
        peers = PeerTable()
        a = await UdpEndpoint.open(peers=peers)
        b = await UdpEndpoint.open()
        got: list[tuple[OscMessage, str]] = []
        a.set_handler(lambda m, s: got.append((m, s)))
        b.set_handler(lambda m, s: got.append((m, s)))
        peers.add(Peer(role="sound", host=target[0], port=target[1], node_id="odd"))
        a.send(hello(1), target)
        a.send(hello(2), "sound")
        a.send_copy(encode(hello(3)), target)
        assert a.unroutable == 2
        a.send(hello(4), b.local_address)
        b.send(hello(5), a.local_address)
        await wait_for(lambda: len(got) >= 2)
        assert sorted(ports(got)) == [4, 5] and not a.closed
        a.close()
        b.close()

    run(main())


def test_port_unreachable_errors_do_not_stop_receiving() -> None:
    async def main() -> None:
        a = await UdpEndpoint.open()
        b = await UdpEndpoint.open()
        closed = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        closed.bind(("127.0.0.1", 0))
        dead_port = closed.getsockname()[1]
        closed.close()
        got: list[tuple[OscMessage, str]] = []
        a.set_handler(lambda m, s: got.append((m, s)))
        for i in range(50):  # each may be answered by ICMP port unreachable
            a.send(hello(i), ("127.0.0.1", dead_port))
            b.send(hello(i), a.local_address)
            await asyncio.sleep(0)
        await wait_for(lambda: len(got) >= 50)
        assert ports(got) == list(range(50))
        assert not a.closed and a.stats.messages_out == 50
        a.close()
        b.close()

    run(main())


def test_replies_to_many_sources_do_not_grow_memory() -> None:
    """A node answers every source (Hello -> Health); spoofed sources must not fill a cache."""

    async def main() -> None:
        a = await UdpEndpoint.open()
        data = hello(1)
        for i in range(2000):  # warm up
            a.send(data, (f"127.9.{i // 250}.{i % 250 + 1}", 9))
        tracemalloc.start()
        before = tracemalloc.get_traced_memory()[0]
        for i in range(20_000):
            a.send(data, (f"127.{10 + i // 62500}.{i // 250 % 250}.{i % 250 + 1}", 9))
        grown = tracemalloc.get_traced_memory()[0] - before
        tracemalloc.stop()
        assert grown < 1_000_000
        a.close()

    run(main())


def _osc_str(text: str) -> bytes:
    raw = text.encode() + b"\0"
    return raw + b"\0" * (-len(raw) % 4)


def _bundle(elements: list[bytes]) -> bytes:
    return _osc_str("#bundle") + bytes(8) + b"".join(struct.pack(">i", len(e)) + e for e in elements)


def test_hostile_bundles_are_counted_and_the_next_message_arrives() -> None:
    async def main() -> None:
        b = await UdpEndpoint.open()
        got: list[tuple[OscMessage, str]] = []
        b.set_handler(lambda m, s: got.append((m, s)))
        nested = encode(hello(0))
        while len(nested) < 60_000:
            nested = _bundle([nested])
        tiny = _osc_str("/x") + _osc_str(",")
        many = _bundle([tiny] * 5000)
        truncated = _bundle([encode(hello(0))])[:-3]
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            for packet in (nested, many, truncated, b"\xff" * 1000, encode(hello(1))):
                s.sendto(packet, ("127.0.0.1", b.port))
            await wait_for(lambda: len(got) >= 1)
        assert ports(got) == [1]
        assert b.stats.dropped[DropReason.MALFORMED] == 3
        assert b.stats.dropped[DropReason.UNKNOWN_ADDRESS] == 5000
        b.close()

    run(main())


def test_the_rate_limit_counts_the_messages_of_a_bundle() -> None:
    """--max-rate bounds the work one source can cause: a 64 KiB bundle of 5,000 messages costs the
    node ~100 ms to parse, so bundling must not multiply the allowed rate by 5,000."""
    clock = Clock()

    async def main() -> None:
        b = await UdpEndpoint.open(max_rate=100.0, clock=clock)
        got: list[tuple[OscMessage, str]] = []
        b.set_handler(lambda m, s: got.append((m, s)))
        b.receive_datagram(_bundle([encode(hello(i)) for i in range(1000)]), "10.0.0.1", 9)
        assert len(got) == 1000  # a bundle larger than the burst still gets through, once
        for i in range(50):
            b.receive_datagram(encode(hello(i)), "10.0.0.1", 9)
        b.receive_datagram(encode(hello(7)), "10.0.0.2", 9)  # another source has its own budget
        assert len(got) == 1001 and b.stats.dropped[DropReason.RATE_LIMITED] == 50
        clock.t += 9.0  # 900 of the 1,000 messages paid back: still over
        b.receive_datagram(encode(hello(8)), "10.0.0.1", 9)
        assert len(got) == 1001
        clock.t += 1.5
        b.receive_datagram(encode(hello(9)), "10.0.0.1", 9)
        assert ports(got)[-1] == 9
        b.close()

    run(main())
