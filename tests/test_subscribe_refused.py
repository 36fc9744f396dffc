"""A refused Subscribe is answered (``/batteur/subscribe/refused``: the pattern and why), at most once a second
per source, and ``batteur echo`` says so once per node instead of printing nothing."""

from __future__ import annotations

import asyncio
import logging
import threading
from collections.abc import Iterator

import pytest

from batteur.tools import echo
from batteur.tools.nodes import Target
from common.config import load_settings
from common.messages import REGISTRY, Hello, OscMessage, Subscribe, SubscribeRefused
from common.runtime import Node
from common.subscribe import MAX_REFUSAL_REPLY_RATE, Subscriptions
from common.transport import UdpEndpoint
from tests.null_core import NullCore
from tests.waiting import wait_for

pytestmark = pytest.mark.timeout(60)


# --------------------------------------------------------------------------- the table


def test_a_refusal_says_why_and_replies_are_limited_per_source_and_in_total() -> None:
    now = [0.0]
    subs = Subscriptions(lambda d, to: None, lambda: now[0], max_subscribers=2)
    assert subs.request(("127.0.0.1", 1), "/a", 5.0) == ""
    assert subs.request(("127.0.0.1", 2), "/b", 5.0) == ""
    assert subs.request(("127.0.0.1", 3), "/c", 5.0) == "table full (2 subscriptions)"
    assert subs.request(("127.0.0.1", 1), "/a", 5.0) == ""  # a renewal is never refused
    reason = subs.request(("127.0.0.1", 4), "/a[bc", 5.0)
    assert reason.startswith("bad pattern") and "'[' without ']'" in reason
    assert subs.refused == 2
    # one reply per source per second
    me = ("127.0.0.1", 3)
    assert subs.may_reply(me)
    assert not subs.may_reply(me)
    now[0] = 0.5
    assert not subs.may_reply(me)
    now[0] = 1.0
    assert subs.may_reply(me)
    assert (subs.replies, subs.replies_suppressed) == (2, 2)
    # many sources at once (spoofed, say): the node never answers more than its overall rate
    now[0] = 10.0
    answered = sum(subs.may_reply(("10.0.0.1", port)) for port in range(1000))
    assert answered == MAX_REFUSAL_REPLY_RATE
    for second in range(100):  # and the sources it remembers stay few
        now[0] = 20.0 + second
        for port in range(50):
            subs.may_reply((f"10.0.{second}.1", port))
    assert len(subs._replied) <= 3 * MAX_REFUSAL_REPLY_RATE


def test_the_reply_is_a_registered_message_that_round_trips() -> None:
    assert REGISTRY.get("/batteur/subscribe/refused") is SubscribeRefused
    reply = SubscribeRefused(node_id="sound-1", pattern="/batteur/*", reason="table full (16 subscriptions)")
    assert reply.to_args() == ["sound-1", "/batteur/*", "table full (16 subscriptions)"]


# --------------------------------------------------------------------------- the node


def quiet_node(node_id: str = "sound-1") -> Node:
    return Node(NullCore(), load_settings({"role": "sound", "node_id": node_id, "discovery": False,
                                            "clock_master": "self"}))


async def started_with_a_full_table() -> tuple[Node, asyncio.Task[None], str, UdpEndpoint]:
    """A running quiet node whose subscription table (one place) a first client has filled, its refusal clock
    stopped at 100 s (every refusal within one interval, however slow this machine): (node, its task, its address,
    the first client)."""
    node = quiet_node()
    node.subscriptions.max_subscribers = 1
    node.subscriptions.clock = lambda: 100.0
    task = asyncio.ensure_future(node.run())
    await wait_for(lambda: node.endpoint is not None)
    assert node.endpoint is not None
    target = node.endpoint.local_address
    first = await UdpEndpoint.open()
    first.send(Subscribe(pattern="/batteur/impact", duration_s=60.0), target)
    await wait_for(lambda: bool(node.subscriptions.active))
    return node, task, target, first


def test_a_node_answers_a_refused_subscribe_once_a_second_however_many_it_gets() -> None:
    async def main() -> None:
        node, task, target, first = await started_with_a_full_table()  # the flood arrives within one second
        me = await UdpEndpoint.open()
        got: list[tuple[OscMessage, str]] = []
        me.set_handler(lambda m, s: got.append((m, s)))
        for _ in range(40):  # the table is full
            me.send(Subscribe(pattern="/batteur/*", duration_s=10.0), target)
        await wait_for(lambda: node.subscriptions.refused == 40)
        await wait_for(lambda: len(got) >= 1)
        me.send(Hello(role="cli", node_id="me", protocol=1, osc_port=me.port), target)  # answered after the flood
        await wait_for(lambda: len(got) >= 2)
        replies = [m for m, _ in got if isinstance(m, SubscribeRefused)]
        assert len(replies) == 1 and got[0][1] == target
        assert replies[0] == SubscribeRefused(node_id="sound-1", pattern="/batteur/*",
                                              reason="table full (1 subscriptions)")
        assert node.subscriptions.replies == 1 and node.subscriptions.replies_suppressed == 39
        # a bad pattern is answered too (another source: its own allowance)
        other = await UdpEndpoint.open()
        answers: list[OscMessage] = []
        other.set_handler(lambda m, s: answers.append(m))
        other.send(Subscribe(pattern="/batteur/{impact", duration_s=10.0), target)
        await wait_for(lambda: bool(answers))
        bad = answers[0]
        assert isinstance(bad, SubscribeRefused) and bad.pattern == "/batteur/{impact"
        assert "'{' without '}'" in bad.reason
        node.request_stop()
        await asyncio.wait_for(task, 3.0)
        for endpoint in (first, me, other):
            endpoint.close()

    asyncio.run(main())


# --------------------------------------------------------------------------- batteur echo


@pytest.fixture
def full_node() -> Iterator[Node]:
    """A node in a thread of its own (echo runs its loop in this one), its subscription table full."""
    ready = threading.Event()
    holder: list[Node] = []

    def setup(node: Node) -> None:
        node.subscriptions.max_subscribers = 2
        for port in (1, 2):
            node.subscriptions.subscribe(("127.0.0.1", port), "/batteur/impact", 3600.0)
        ready.set()

    def serve() -> None:
        node = quiet_node("sound-full")
        holder.append(node)
        asyncio.run(node.run(setup=setup))

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    assert ready.wait(10)
    yield holder[0]
    holder[0].request_stop()
    thread.join(10)


def test_echo_says_once_that_a_node_refused_and_still_exits_as_before(full_node: Node,
                                                                      capsys: pytest.CaptureFixture[str]) -> None:
    assert full_node.endpoint is not None
    address = full_node.endpoint.local_address
    assert echo.main(["/batteur/*", "--node", address, "--duration", "1"]) == 0  # the node answered its Health
    err = capsys.readouterr().err
    said = [line for line in err.splitlines() if "refused" in line]
    assert said == [f"batteur echo: node sound-full at {address} refused /batteur/*: table full (2 subscriptions)"]


def test_echo_reports_each_nodes_refusal_of_its_own_pattern_once() -> None:
    a = Target(host="127.0.0.1", port=9000, ip="127.0.0.1")
    b = Target(host="rig-b", port=9000, ip="127.0.0.2")
    notes = echo.Refusals("/batteur/*", [a, b])
    full = SubscribeRefused(node_id="a1", pattern="/batteur/*", reason="table full (16 subscriptions)")
    assert notes.line(full, "127.0.0.1:9000") == ("batteur echo: node a1 at 127.0.0.1:9000 refused /batteur/*: "
                                                  "table full (16 subscriptions)")
    assert notes.line(full, "127.0.0.1:9000") is None  # the renewal 5 s later is refused again: said once
    assert notes.line(full.model_copy(update={"node_id": "b1"}), "127.0.0.2:9000") == (
        "batteur echo: node b1 at rig-b:9000 refused /batteur/*: table full (16 subscriptions)")
    # a copy of someone else's refusal (another pattern) is not ours
    assert notes.line(full.model_copy(update={"pattern": "/x"}), "127.0.0.1:9001") is None
    assert notes.line(Hello(role="cli", node_id="x", protocol=1, osc_port=1), "127.0.0.1:9000") is None


# --------------------------------------------------------------------------- refusals the model makes, logs, counts


def test_a_subscribe_the_model_refuses_is_answered_too() -> None:
    """A duration of 0 (the model takes more than 0) was counted as out of range but never answered, unlike a full
    table or a bad pattern: ``batteur echo`` waited for copies that would never come."""
    async def main() -> None:
        node = quiet_node()
        task = asyncio.ensure_future(node.run())
        await wait_for(lambda: node.endpoint is not None)
        assert node.endpoint is not None
        target = node.endpoint.local_address
        answers: list[OscMessage] = []
        clients = []
        for args in (["/batteur/*", 0.0], [7, 10.0]):  # out of range; a number for the pattern
            client = await UdpEndpoint.open()
            clients.append(client)
            client.set_handler(lambda m, s: answers.append(m))
            client.send_raw(Subscribe.ADDRESS, args, target)
            await wait_for(lambda: len(answers) == len(clients))
        zero, number = answers
        assert isinstance(zero, SubscribeRefused) and zero.node_id == "sound-1" and zero.pattern == "/batteur/*"
        assert "duration_s" in zero.reason and "0" in zero.reason
        assert isinstance(number, SubscribeRefused) and number.pattern == "/" and "pattern" in number.reason
        assert not node.subscriptions.active
        health = node.health()
        assert (health.dropped_range, health.dropped_type, health.dropped) == (1, 1, 2)
        node.request_stop()
        await asyncio.wait_for(task, 3.0)
        for client in clients:
            client.close()

    asyncio.run(main())


def test_refused_subscriptions_are_warnings_a_few_at_most_and_counted_in_health(
        caplog: pytest.LogCaptureFixture) -> None:
    """A bad pattern or a full table is the client's mistake: it was logged at ERROR and not counted."""
    async def main() -> None:
        node, task, target, client = await started_with_a_full_table()  # one log interval
        for k in range(30):
            pattern = "/batteur/[" if k % 2 else f"/batteur/x{k}"  # a bad pattern, or a full table
            client.send(Subscribe(pattern=pattern, duration_s=10.0), target)
        await wait_for(lambda: node.subscriptions.refused == 30)
        health = node.health()
        assert (health.dropped_other, health.dropped) == (30, 30)
        node.request_stop()
        await asyncio.wait_for(task, 3.0)
        client.close()

    with caplog.at_level(logging.INFO, logger="batteur.runtime"):
        asyncio.run(main())
    refusals = [r for r in caplog.records if r.name == "batteur.runtime" and "refused" in r.getMessage()]
    assert [r.levelno for r in refusals] == [logging.WARNING]
