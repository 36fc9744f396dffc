"""A node answers Hellos within a budget per sender host (common/runtime.py, ``HELLO_ANSWER_*``): a forged source
cannot turn it into a reflector. Unbudgeted, one 60 kB datagram bundling 1363 tool Hellos drew 2726 datagrams,
376 kB (Health and ClockStatus to each)."""

from __future__ import annotations

import asyncio
import socket
from typing import NamedTuple

import pytest

import common.runtime
from common.config import load_settings
from common.core import Core
from common.messages import (
    PROTOCOL_VERSION,
    ClockPing,
    ClockPong,
    Health,
    Hello,
    OscMessage,
    Skeleton,
    decode,
    encode,
)
from common.messages.codec import encode_bundle
from common.messages.system import TOOL_ROLE, ClockStatus
from common.runtime import HELLO_ANSWER_BURST, Node
from common.stats import DropReason
from services.physics.core import PhysicsCore
from tests.null_core import NullCore

BUNDLE_BYTES = 60_000
"""The bundle of Hellos sent, at most this many bytes (one UDP datagram)."""


@pytest.fixture
def answers_never_refill(monkeypatch: pytest.MonkeyPatch) -> None:
    """The burst only, so how many are answered does not depend on how fast the node goes (read when a node is
    made)."""
    monkeypatch.setattr(common.runtime, "HELLO_ANSWER_RATE_HZ", 0.0)


def _socket(host: str) -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind((host, 0))
    sock.setblocking(False)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 8 << 20)  # all of an unbudgeted answer fits
    return sock


async def _answers_until(sock: socket.socket, last: type[OscMessage]) -> list[tuple[OscMessage, int]]:
    """Each message received on ``sock`` (with its datagram's size, bytes) up to the first ``last``, included."""
    loop = asyncio.get_running_loop()
    got: list[tuple[OscMessage, int]] = []
    while not got or not isinstance(got[-1][0], last):
        data = await asyncio.wait_for(loop.sock_recv(sock, 65536), 20.0)
        (message,) = decode(data).messages  # one message a datagram
        got.append((message, len(data)))
    return got


class Flood(NamedTuple):
    hellos: int
    """Hellos in the bundle."""
    sent_bytes: int
    """The bundle's size, bytes."""
    answers: list[OscMessage]
    """What came back to the flooding socket before the pong."""
    answered_bytes: int
    """Their datagrams' sizes, bytes."""
    rate_limited: int
    """The node's count of dropped ``rate_limited`` messages once the pong came."""
    other_answered: bool
    """Whether the Hello from another host, sent after, was answered with a Health."""


async def flood_of_hellos(core: Core, role: str, hello_role: str) -> Flood:
    """Run ``core`` as a ``role`` node; send it one datagram bundling as many ``hello_role`` Hellos as fit, then a
    clock ping (answered once the bundle was handled: one sender's datagrams are handled in order), then a Hello
    from another loopback host."""
    node = Node(core, load_settings({"role": role, "discovery": False, "clock_master": "self",  # type: ignore[arg-type]
                                     "oscquery": False}))
    await node.start()
    assert node.endpoint is not None
    to = ("127.0.0.1", node.endpoint.port)
    loop = asyncio.get_running_loop()
    flooder, other = _socket("127.0.0.1"), _socket("127.0.0.2")
    try:
        hello = Hello(role=hello_role, node_id="forged", protocol=PROTOCOL_VERSION, osc_port=flooder.getsockname()[1])
        count = (BUNDLE_BYTES - 16) // (4 + len(encode(hello)))
        bundle = encode_bundle([hello] * count)
        assert len(bundle) <= BUNDLE_BYTES
        await loop.sock_sendto(flooder, bundle, to)
        await loop.sock_sendto(flooder, encode(ClockPing(node_id="forged", seq=1, t_send=0.0)), to)
        got = await _answers_until(flooder, ClockPong)
        rate_limited = node.endpoint.stats.dropped[DropReason.RATE_LIMITED]
        await loop.sock_sendto(other, encode(hello), to)  # another host: a budget of its own
        other_answered = isinstance((await _answers_until(other, Health))[0][0], Health)
        return Flood(count, len(bundle), [m for m, _ in got[:-1]], sum(size for _, size in got[:-1]), rate_limited,
                     other_answered)
    finally:
        flooder.close()
        other.close()
        await node.stop()


@pytest.mark.usefixtures("answers_never_refill")
@pytest.mark.parametrize(("hello_role", "answer_types"), [(TOOL_ROLE, {Health, ClockStatus}), ("sound", {Health})])
def test_a_bundle_of_hellos_gets_the_budget_of_answers_back(hello_role: str,
                                                            answer_types: set[type[OscMessage]]) -> None:
    flood = asyncio.run(flood_of_hellos(NullCore(), "sound", hello_role))
    assert flood.hellos > 1000
    assert {type(m) for m in flood.answers} == answer_types
    assert len(flood.answers) == HELLO_ANSWER_BURST * len(answer_types)  # the burst, then none (a tool: 2 a Hello)
    assert flood.answered_bytes < flood.sent_bytes / 10  # no reflector: far fewer bytes back than sent
    assert flood.rate_limited == flood.hellos - HELLO_ANSWER_BURST  # the rest counted (Health's dropped_other)
    assert flood.other_answered


@pytest.mark.usefixtures("answers_never_refill")
def test_the_physics_skeleton_a_hello_draws_is_within_the_budget(strike_core: PhysicsCore) -> None:
    """Physics' core answers a Hello with its Skeleton: an over-budget Hello does not reach it."""
    flood = asyncio.run(flood_of_hellos(strike_core, "physics", "graphics"))
    assert sum(isinstance(m, Health) for m in flood.answers) == HELLO_ANSWER_BURST
    assert sum(isinstance(m, Skeleton) for m in flood.answers) == HELLO_ANSWER_BURST
    assert flood.answered_bytes < flood.sent_bytes
    assert flood.rate_limited == flood.hellos - HELLO_ANSWER_BURST
    assert flood.other_answered
