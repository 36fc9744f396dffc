"""A node's Health reports the refusals it counted but did not answer (over a sender's reply budget): undecodable
controls the transport dropped unanswered (``decode_unanswered``, every node) and refusals the physics core did not
answer (``replies_unanswered``). Without them a flood of bad packets showed in ``dropped`` only, and the answers a
sender missed were visible nowhere.

Nodes run in-process on loopback (no discovery, no OSCQuery); the reply budgets do not refill (rate 0), so the
counts are exact whatever the machine's speed.
"""

from __future__ import annotations

import asyncio
from collections.abc import Sequence

import pytest

import common.transport
import services.physics.core
from common.config import load_settings
from common.core import Core
from common.messages import Health, Hello, OscMessage
from common.messages.physics import CartesianTarget, PhysicsRejected
from common.messages.sound import SoundRejected
from common.runtime import Node
from common.transport import DECODE_REPLY_BURST, UdpEndpoint
from services.physics.core import REPLY_BURST, PhysicsCore
from tests.null_core import NullCore
from tests.waiting import wait_for

pytestmark = pytest.mark.timeout(120)

RawSend = tuple[str, list[int | float | str]]
"""An OSC address and its arguments, sent as they are (no model checks them)."""

FLOOD = 5 * int(max(DECODE_REPLY_BURST, REPLY_BURST))
BAD_LEVEL: RawSend = ("/batteur/sound/level", ["snare", "loud"])  # a sound control whose level is no number
BAD_TARGET: RawSend = ("/batteur/physics/target", ["left_hand", 1, 0.0, 0.0, 0.4, 1.0])  # 6 of its 9 arguments
UNREACHABLE = CartesianTarget(limb="left_hand", time=0.5, x=0.0, y=4.0, z=1.0, vx=0.0, vy=0.0, vz=0.0)
"""Decodes, and the strike scene refuses it (it needs the drummer scene): a refusal of the physics core."""


@pytest.fixture
def budgets_never_refill(monkeypatch: pytest.MonkeyPatch) -> None:
    """Reply budgets of the burst only, so what is answered and what is not does not depend on how fast the
    flood goes (read when an endpoint or a core is made)."""
    monkeypatch.setattr(common.transport, "DECODE_REPLY_RATE_HZ", 0.0)
    monkeypatch.setattr(services.physics.core, "REPLY_RATE_HZ", 0.0)




async def health_after(core: Core, role: str,
                        flood: Sequence[RawSend | OscMessage]) -> tuple[Health, list[OscMessage]]:
    """Run ``core`` as a ``role`` node, send it ``flood`` from one loopback socket, then a Hello: the Health it
    answers and every message that came back before it (the node handles one sender's datagrams in order)."""
    node = Node(core, load_settings({"role": role, "discovery": False, "clock_master": "self",  # type: ignore[arg-type]
                                     "oscquery": False}))
    return await node_health_after(node, flood)


async def node_health_after(node: Node, flood: Sequence[RawSend | OscMessage]) -> tuple[Health, list[OscMessage]]:
    """Start ``node``, send it ``flood`` from one loopback socket, then a Hello: the Health it answers and every
    message that came back before it; the node is stopped after."""
    await node.start()
    assert node.endpoint is not None
    client = await UdpEndpoint.open("127.0.0.1")
    got: list[OscMessage] = []
    client.set_handler(lambda message, _: got.append(message))
    try:
        to = node.endpoint.local_address
        for item in flood:
            if isinstance(item, OscMessage):
                client.send(item, to)
            else:
                client.send_raw(*item, to)
        client.send(Hello(role="test", node_id="test-1", protocol=1, osc_port=client.port), to)
        await wait_for(lambda: any(isinstance(m, Health) for m in got), 20.0)
        health = next(m for m in got if isinstance(m, Health))
        return health, got[:got.index(health)]
    finally:
        client.close()
        await node.stop()


@pytest.mark.usefixtures("budgets_never_refill")
def test_a_node_reports_the_undecodable_controls_it_did_not_answer() -> None:
    misdirected = 10  # physics controls sent to a sound node: never answered there, so none was held back
    health, before = asyncio.run(health_after(NullCore(), "sound", [BAD_TARGET] * misdirected + [BAD_LEVEL] * FLOOD))
    answered = sum(isinstance(m, SoundRejected) for m in before)
    assert answered == DECODE_REPLY_BURST and len(before) == answered  # the burst is answered ...
    assert health.decode_unanswered == FLOOD - DECODE_REPLY_BURST  # ... the rest counted, and reported
    assert health.dropped_type == FLOOD + misdirected  # every one was dropped, answered or not
    assert health.replies_unanswered == 0  # a core without the count: none


@pytest.mark.usefixtures("budgets_never_refill")
def test_the_physics_node_reports_the_refusals_it_did_not_answer(strike_core: PhysicsCore) -> None:
    health, before = asyncio.run(health_after(strike_core, "physics", [UNREACHABLE] * FLOOD))
    answered = [m for m in before if isinstance(m, PhysicsRejected)]
    assert len(answered) == REPLY_BURST and all("drummer scene" in m.reason for m in answered)
    assert health.replies_unanswered == FLOOD - REPLY_BURST
    assert health.dropped_other == FLOOD  # refused by the core: counted as dropped too
    assert health.decode_unanswered == 0  # they all decoded


def test_health_carries_both_counts_last_on_the_wire() -> None:
    """Appended after ``peers``: a reader that takes Health's arguments by position (a Pd patch) finds the
    earlier ones where they were."""
    names = [f.name for f in Health.wire_fields()]
    assert names[names.index("peers"):][:3] == ["peers", "decode_unanswered", "replies_unanswered"]
    health = Health(node_id="n-1", role="sound", protocol=1, time=1.5, rate_hz=0.0, target_rate_hz=0.0, overruns=0,
                    messages_in=0, messages_out=0, dropped=0, dropped_malformed=0, dropped_unknown=0, dropped_type=0,
                    dropped_range=0, dropped_other=0, late=0, peers=2, decode_unanswered=7, replies_unanswered=3)
    at = names.index("peers") + 1  # ``time`` is two arguments
    assert health.to_args()[at:at + 3] == [2, 7, 3]
    assert Health.from_args(health.to_args()) == health
