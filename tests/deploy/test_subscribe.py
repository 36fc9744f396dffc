"""Subscribe: a node forwards copies of matching messages it sends or receives (``batteur echo``)."""

from __future__ import annotations

import asyncio
from typing import ClassVar

import pytest

from common.config import load_settings
from common.core import Outgoing
from common.messages import Health, Hello, Impact, OscMessage, Subscribe
from common.runtime import Node
from common.subscribe import PatternError, Subscriptions, matches, pattern_regex
from common.transport import UdpEndpoint
from tests.waiting import wait_for

pytestmark = pytest.mark.timeout(60)


@pytest.mark.parametrize(
    ("pattern", "address", "expected"),
    [
        ("/batteur/impact", "/batteur/impact", True),
        ("/batteur/impact", "/batteur/impact/end", False),
        ("/batteur/*", "/batteur/impact", True),
        ("/batteur/*", "/batteur/impact/end", False),
        ("/batteur/*/*", "/batteur/impact/end", True),
        ("/batteur/sound/*", "/batteur/sound/level", True),
        ("/batteur/{impact,damping}", "/batteur/damping", True),
        ("/batteur/{impact,damping}", "/batteur/health", False),
        ("/batteur/h?llo", "/batteur/hello", True),
        ("/batteur/[gh]ello", "/batteur/hello", True),
        ("/batteur/[!h]ello", "/batteur/hello", False),
        ("/batteur/[a-i]ealth", "/batteur/health", True),
        ("//level", "/batteur/sound/level", True),
        ("/batteur//end", "/batteur/impact/end", True),
        ("/batteur/imp.ct", "/batteur/impact", False),  # '.' is literal
    ],
)
def test_osc_patterns(pattern: str, address: str, expected: bool) -> None:
    assert matches(pattern, address) is expected


@pytest.mark.parametrize("pattern", ["batteur", "/a[bc", "/a{b,c", "/a[]"])
def test_bad_patterns_are_refused(pattern: str) -> None:
    with pytest.raises(PatternError):
        pattern_regex(pattern)


def test_subscriptions_are_bounded_expire_and_rate_limited() -> None:
    now = [0.0]
    sent: list[tuple[bytes, tuple[str, int]]] = []
    subs = Subscriptions(lambda d, to: sent.append((d, to)), lambda: now[0], max_subscribers=2, max_rate=10.0)
    assert subs.subscribe(("127.0.0.1", 1), "/a/*", 5.0)
    assert subs.subscribe(("127.0.0.1", 2), "/b", 1.0)
    assert not subs.subscribe(("127.0.0.1", 3), "/c", 1.0)  # full
    assert not subs.subscribe(("127.0.0.1", 4), "nope", 1.0)  # bad pattern
    assert subs.refused == 2
    assert subs.subscribe(("127.0.0.1", 2), "/b", 10.0)  # renewal is not a new subscriber
    subs.offer("/a/x", lambda: b"ax")
    subs.offer("/b", lambda: b"b")
    subs.offer("/z", lambda: b"z")
    assert sent == [(b"ax", ("127.0.0.1", 1)), (b"b", ("127.0.0.1", 2))]
    # rate limit: 10 copies/s, burst 10 -> the 11th to 30th within the same instant are dropped
    for _ in range(30):
        subs.offer("/a/y", lambda: b"ay")
    assert subs.dropped == 21 and subs.forwarded == 11
    # expiry
    now[0] = 6.0
    subs.offer("/a/x", lambda: b"ax")
    assert ("127.0.0.1", 1) not in [s.to for s in subs.active.values()]
    assert len(subs.active) == 1
    now[0] = 20.0
    subs.expire()
    assert not subs


class ReplyCore:
    """Answers every Impact with a Hello to the sender; steps at 0 Hz."""

    ROLE: ClassVar[str] = "echo"
    rate_hz = 0.0

    def handle(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        if isinstance(message, Impact):
            return [Outgoing(Hello(role="echo", node_id="core", protocol=1, osc_port=message.seq), "reply")]
        return []

    def step(self, now: float) -> list[Outgoing]:
        return []


def impact(seq: int) -> Impact:
    return Impact(seq=seq, time=1.0, instrument="snare", zone="centre", r=0.25, theta=0.0, velocity=2.0,
                  impulse=0.0625, peak_force=10.0, duration=0.00390625, part="stick")




def test_node_forwards_matching_messages_sent_and_received_until_expiry() -> None:
    async def main() -> None:
        node = Node(ReplyCore(), load_settings({"role": "echo", "discovery": False, "clock_master": "self"}),
                    health_interval_s=0.05)
        task = asyncio.ensure_future(node.run())
        await wait_for(lambda: node.endpoint is not None)
        assert node.endpoint is not None
        target = node.endpoint.local_address
        echo = await UdpEndpoint.open()  # the `batteur echo` side
        copies: list[tuple[OscMessage, str]] = []
        echo.set_handler(lambda m, s: copies.append((m, s)))
        sender = await UdpEndpoint.open()  # someone else talking to the node
        answers: list[OscMessage] = []
        sender.set_handler(lambda m, s: answers.append(m))

        echo.send(Subscribe(pattern="/batteur/{impact,hello}", duration_s=0.6), target)
        await wait_for(lambda: bool(node.subscriptions.active))
        sender.send(impact(7), target)  # received by the node -> copied
        await wait_for(lambda: any(isinstance(m, Hello) for m in answers))  # the node's reply -> copied
        await wait_for(lambda: len(copies) >= 2)
        kinds = {type(m) for m, _ in copies}
        assert kinds == {Impact, Hello}
        got_impact = next(m for m, _ in copies if isinstance(m, Impact))
        assert got_impact == impact(7)
        got_hello = next(m for m, _ in copies if isinstance(m, Hello))
        assert isinstance(got_hello, Hello) and got_hello.osc_port == 7
        assert all(source == target for _, source in copies)  # copies come from the node's own socket
        # messages that do not match (Health is not in the pattern) are not copied
        sender.send(Hello(role="tester", node_id="t", protocol=1, osc_port=sender.port), target)
        await wait_for(lambda: any(isinstance(m, Health) for m in answers))
        await asyncio.sleep(0.05)
        assert not any(isinstance(m, Health) for m, _ in copies)
        assert node.subscriptions.forwarded >= 3  # impact, hello (reply), hello (from tester)
        # the copies are not counted as the node's traffic
        out_before = node.endpoint.stats.messages_out
        # after expiry nothing more is copied
        await asyncio.sleep(0.7)
        count = len(copies)
        sender.send(impact(8), target)
        await wait_for(lambda: sum(isinstance(m, Hello) and m.osc_port == 8 for m in answers) == 1)
        await asyncio.sleep(0.1)
        assert len(copies) == count
        assert not node.subscriptions.active
        assert node.endpoint.stats.messages_out >= out_before + 1
        node.request_stop()
        await asyncio.wait_for(task, 3.0)
        echo.close()
        sender.close()

    asyncio.run(main())


def test_subscribe_with_a_bad_pattern_is_refused_and_the_node_carries_on() -> None:
    async def main() -> None:
        node = Node(ReplyCore(), load_settings({"role": "echo", "discovery": False, "clock_master": "self"}))
        task = asyncio.ensure_future(node.run())
        await wait_for(lambda: node.endpoint is not None)
        assert node.endpoint is not None
        echo = await UdpEndpoint.open()
        echo.send(Subscribe(pattern="/a[bc", duration_s=1.0), node.endpoint.local_address)
        await wait_for(lambda: node.subscriptions.refused == 1)
        assert not node.subscriptions.active
        node.request_stop()
        await asyncio.wait_for(task, 3.0)
        echo.close()

    asyncio.run(main())
