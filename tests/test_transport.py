"""The UDP transport on loopback: round trips, every drop reason, bursts, big datagrams, timetags."""

from __future__ import annotations

import asyncio
import socket
import time
from collections.abc import Awaitable, Coroutine
from typing import Any

import pytest

from common.messages import DropReason, Hello, Impact, OscMessage, Pose, encode, encode_bundle, encode_raw
from common.messages.codec import RawMessage
from common.peers import Peer, PeerTable
from common.transport import UdpEndpoint, format_address, parse_address
from tests.waiting import wait_for

pytestmark = pytest.mark.timeout(60)


def run(coro: Coroutine[Any, Any, Any]) -> Any:
    return asyncio.run(coro)




def hello(i: int = 0, node_id: str = "n") -> Hello:
    return Hello(role="physics", node_id=node_id, protocol=1, osc_port=i)


def impact(seq: int) -> Impact:
    return Impact(seq=seq, time=12.25 + seq, instrument="snare", zone="centre", r=0.25, theta=0.5, velocity=3.0,
                  impulse=0.0625, peak_force=120.0, duration=0.00390625, part="right_stick_tip")


class Receiver:
    def __init__(self, endpoint: UdpEndpoint) -> None:
        self.got: list[tuple[OscMessage, str]] = []
        endpoint.set_handler(lambda m, s: self.got.append((m, s)))

    async def until(self, n: int, timeout: float = 5.0) -> None:
        await wait_for(lambda: len(self.got) >= n, timeout)


def udp_sender(host: str = "127.0.0.1") -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind((host, 0))
    return sock


def test_addresses_parse_and_format() -> None:
    assert parse_address("127.0.0.1:9000") == ("127.0.0.1", 9000)
    assert parse_address("[::1]:9000") == ("::1", 9000)
    assert parse_address("sound.local:1") == ("sound.local", 1)
    for bad in ("nohost", "::1:9000", "h:0", "h:99999", "h:x"):
        with pytest.raises(ValueError):
            parse_address(bad)
    assert format_address("::1", 5) == "[::1]:5"
    assert format_address("10.0.0.1", 5) == "10.0.0.1:5"


def test_round_trip_by_address_tuple_role_and_bundle() -> None:
    async def main() -> None:
        peers = PeerTable()
        a = await UdpEndpoint.open(peers=peers)
        b = await UdpEndpoint.open()
        rx = Receiver(b)
        peers.add(Peer(role="sound", host="127.0.0.1", port=b.port, node_id="sound-1"))
        a.send(hello(1), b.local_address)
        a.send(hello(2), ("127.0.0.1", b.port))
        a.send(impact(3), "sound")
        a.send_bundle([hello(4), impact(5)], "sound")
        a.send(hello(6), "graphics")  # no such peer: not sent, counted
        await rx.until(5)
        await asyncio.sleep(0.05)
        assert [m for m, _ in rx.got] == [hello(1), hello(2), impact(3), hello(4), impact(5)]
        assert {s for _, s in rx.got} == {a.local_address}
        assert a.stats.messages_out == 5 and b.stats.messages_in == 5
        assert a.unroutable == 1
        assert b.stats.dropped_total == 0
        a.close()
        b.close()

    run(main())


def test_localhost_name_and_ipv6() -> None:
    async def main() -> None:
        a = await UdpEndpoint.open()
        b = await UdpEndpoint.open()
        rx = Receiver(b)
        a.send(hello(1), f"localhost:{b.port}")
        await rx.until(1)
        a.close()
        b.close()
        if not socket.has_ipv6:
            return
        try:
            c = await UdpEndpoint.open("::1")
        except OSError:
            pytest.skip("no IPv6 loopback")
        d = await UdpEndpoint.open("::1")
        rx6 = Receiver(d)
        c.send(hello(2), d.local_address)
        await rx6.until(1)
        assert rx6.got[0][1] == c.local_address
        assert c.local_address.startswith("[::1]:")
        c.close()
        d.close()

    run(main())


def test_raw_messages_without_a_model() -> None:
    async def main() -> None:
        a = await UdpEndpoint.open()
        b = await UdpEndpoint.open()
        raws: list[tuple[RawMessage, str]] = []
        b.add_raw_route("/batteur/sound/param/", lambda raw, src: raws.append((raw, src)))
        a.send_raw("/batteur/sound/param/snare/tension", [0.5, 3, "x"], b.local_address)
        a.send_raw("/elsewhere", [1], b.local_address)
        await wait_for(lambda: b.stats.dropped_total + len(raws) >= 2)
        assert raws[0][0].address == "/batteur/sound/param/snare/tension"
        assert raws[0][0].args == [0.5, 3, "x"]
        assert b.stats.dropped[DropReason.UNKNOWN_ADDRESS] == 1
        a.close()
        b.close()

    run(main())


# one bad datagram per drop reason that decoding finds; each sent between two good messages
CODEC_CASES: dict[DropReason, bytes] = {
    DropReason.MALFORMED: b"\x00\x01garbage that is no OSC packet",
    DropReason.UNKNOWN_ADDRESS: encode_raw("/batteur/no/such/thing", [1, 2.0]),
    DropReason.WRONG_ARITY: encode_raw("/batteur/hello", ["physics", "n", 1]),
    DropReason.WRONG_TYPE: encode_raw("/batteur/hello", ["physics", "n", "one", 9000]),
    DropReason.OUT_OF_RANGE: encode_raw("/batteur/hello", ["physics", "n", 1, 70000]),
}


@pytest.mark.parametrize("reason", list(CODEC_CASES), ids=str)
def test_bad_input_is_dropped_counted_and_good_messages_still_arrive(reason: DropReason) -> None:
    async def main() -> None:
        b = await UdpEndpoint.open()
        rx = Receiver(b)
        with udp_sender() as s:
            s.sendto(encode(hello(1)), ("127.0.0.1", b.port))
            s.sendto(CODEC_CASES[reason], ("127.0.0.1", b.port))
            s.sendto(encode(hello(2)), ("127.0.0.1", b.port))
            await rx.until(2)
        await wait_for(lambda: b.stats.dropped_total >= 1)
        assert [m.osc_port for m, _ in rx.got] == [1, 2]  # type: ignore[attr-defined]
        assert b.stats.dropped[reason] == 1
        assert b.stats.dropped_total == 1
        b.close()

    run(main())


def test_one_bad_message_in_a_bundle_keeps_the_rest() -> None:
    async def main() -> None:
        b = await UdpEndpoint.open()
        rx = Receiver(b)
        from pythonosc.osc_bundle_builder import IMMEDIATELY, OscBundleBuilder
        from pythonosc.osc_message_builder import OscMessageBuilder

        builder = OscBundleBuilder(IMMEDIATELY)
        contents: list[list[Any]] = [["physics", "n", 1, 1], ["physics", "n", 1, -5], ["physics", "n", 1, 3]]
        for args in contents:
            mb = OscMessageBuilder("/batteur/hello")
            for a in args:
                mb.add_arg(a)
            builder.add_content(mb.build())  # type: ignore[arg-type]
        with udp_sender() as s:
            s.sendto(builder.build().dgram, ("127.0.0.1", b.port))
            await rx.until(2)
        assert [m.osc_port for m, _ in rx.got] == [1, 3]  # type: ignore[attr-defined]
        assert b.stats.dropped[DropReason.OUT_OF_RANGE] == 1
        b.close()

    run(main())


def test_oversize_datagram_is_dropped() -> None:
    async def main() -> None:
        b = await UdpEndpoint.open(max_datagram=1024)
        rx = Receiver(b)
        big = Pose(time=1.0, layout=0, values=tuple(0.5 for _ in range(400)))  # ~1.6 KB
        with udp_sender() as s:
            s.sendto(encode(hello(1)), ("127.0.0.1", b.port))
            s.sendto(encode(big), ("127.0.0.1", b.port))
            s.sendto(encode(hello(2)), ("127.0.0.1", b.port))
            await rx.until(2)
        await wait_for(lambda: b.stats.dropped_total >= 1)
        assert b.stats.dropped[DropReason.OVERSIZE] == 1
        # and we refuse to send one
        b.send(big, b.local_address)
        assert b.send_errors == 1 and b.stats.messages_out == 0
        b.close()

    run(main())


def test_source_outside_the_allow_list_is_dropped() -> None:
    async def main() -> None:
        b = await UdpEndpoint.open(allow=["127.0.0.1/32"])
        rx = Receiver(b)
        with udp_sender("127.0.0.1") as ok, udp_sender("127.0.0.2") as stranger:
            ok.sendto(encode(hello(1)), ("127.0.0.1", b.port))
            stranger.sendto(encode(hello(99)), ("127.0.0.1", b.port))
            ok.sendto(encode(hello(2)), ("127.0.0.1", b.port))
            await rx.until(2)
            await wait_for(lambda: b.stats.dropped_total >= 1)
        assert [m.osc_port for m, _ in rx.got] == [1, 2]  # type: ignore[attr-defined]
        assert b.stats.dropped[DropReason.NOT_ALLOWED] == 1
        b.close()

    run(main())


def test_rate_limit_per_source() -> None:
    class Frozen:
        t = 100.0

        def __call__(self) -> float:
            return self.t

    clock = Frozen()

    async def main() -> None:
        b = await UdpEndpoint.open(max_rate=10.0, max_burst=3, clock=clock)
        rx = Receiver(b)
        with udp_sender("127.0.0.1") as s1, udp_sender("127.0.0.3") as s2:
            for i in range(5):
                s1.sendto(encode(hello(i)), ("127.0.0.1", b.port))
            s2.sendto(encode(hello(50)), ("127.0.0.1", b.port))  # another source has its own budget
            await wait_for(lambda: len(rx.got) + b.stats.dropped_total >= 6)
            assert sorted(m.osc_port for m, _ in rx.got) == [0, 1, 2, 50]  # type: ignore[attr-defined]
            assert b.stats.dropped[DropReason.RATE_LIMITED] == 2
            clock.t += 0.25  # 2.5 tokens back at 10 per second
            s1.sendto(encode(hello(7)), ("127.0.0.1", b.port))
            await rx.until(5)
        b.close()

    run(main())


def test_a_raising_handler_does_not_stop_the_endpoint() -> None:
    async def main() -> None:
        a = await UdpEndpoint.open()
        b = await UdpEndpoint.open()
        got: list[int] = []

        def handler(message: OscMessage, source: str) -> None:
            assert isinstance(message, Hello)
            if message.node_id == "boom":
                raise RuntimeError("handler bug")
            got.append(message.osc_port)

        b.set_handler(handler)
        a.send(hello(1), b.local_address)
        a.send(hello(2, node_id="boom"), b.local_address)
        a.send(hello(3), b.local_address)
        await wait_for(lambda: len(got) >= 2)
        assert got == [1, 3]
        assert b.stats.dropped[DropReason.HANDLER_ERROR] == 1
        assert b.stats.messages_in == 3
        a.close()
        b.close()

    run(main())


def test_burst_of_2000_messages_loses_nothing() -> None:
    async def main() -> None:
        a = await UdpEndpoint.open()
        b = await UdpEndpoint.open()
        rx = Receiver(b)
        for i in range(2000):  # all sent before the receiver gets a chance to read one
            a.send(impact(i), b.local_address)
        await rx.until(2000, timeout=20)
        assert [m.seq for m, _ in rx.got] == list(range(2000))  # type: ignore[attr-defined]
        assert b.stats.dropped_total == 0
        a.close()
        b.close()

    run(main())


def test_60_kib_datagram_is_received() -> None:
    async def main() -> None:
        a = await UdpEndpoint.open()
        b = await UdpEndpoint.open()
        rx = Receiver(b)
        values = tuple(float(i % 1000) for i in range(12_400))
        pose = Pose(time=3.5, layout=2, values=values)
        data = encode(pose)
        assert 60 * 1024 <= len(data) <= 65507
        a.send(pose, b.local_address)
        await rx.until(1)
        assert rx.got[0][0] == pose
        a.close()
        b.close()

    run(main())


def test_future_timetagged_bundle_is_delivered_at_once() -> None:
    async def main() -> None:
        b = await UdpEndpoint.open()
        rx = Receiver(b)
        packet = encode_bundle([hello(1), impact(2)], timetag=time.time() + 3600)
        t0 = time.monotonic()
        with udp_sender() as s:
            s.sendto(packet, ("127.0.0.1", b.port))
            await rx.until(2, timeout=2.0)
        assert time.monotonic() - t0 < 2.0
        b.close()

    run(main())


def test_endpoint_keeps_serving_while_the_loop_runs_other_work() -> None:
    """The handler runs on the loop; a slow coroutine elsewhere only delays, never loses, messages."""

    async def main() -> None:
        a = await UdpEndpoint.open()
        b = await UdpEndpoint.open()
        rx = Receiver(b)

        async def busy() -> None:
            time.sleep(0.2)  # blocks the loop while datagrams queue in the kernel

        task: Awaitable[None] = asyncio.ensure_future(busy())
        for i in range(500):
            a.send(impact(i), b.local_address)
        await task
        await rx.until(500)
        a.close()
        b.close()

    run(main())


def test_closed_endpoint_refuses_to_send() -> None:
    async def main() -> None:
        a = await UdpEndpoint.open()
        a.close()
        assert a.closed
        with pytest.raises(RuntimeError):
            a.send(hello(), "127.0.0.1:9")

    run(main())
