"""A control message the transport cannot decode (wrong argument count or type, a value out of range) is answered to
its sender with its service's refusal, within a reply budget per sender host, and by that service's node only; a
stream message never is."""

from __future__ import annotations

import asyncio

import pytest

from common.config import load_settings
from common.messages import OscMessage
from common.messages.graphics import GraphicsRejected
from common.messages.interaction import InteractionError
from common.messages.physics import PhysicsRejected
from common.messages.sound import SoundRejected
from common.runtime import Node
from common.transport import DECODE_REPLY_BURST, UdpEndpoint, decode_refusal
from tests.null_core import NullCore
from tests.waiting import wait_for

pytestmark = pytest.mark.timeout(60)

BAD_TARGET = ("/batteur/physics/target", ["left_hand", 1, 0.0, 0.0, 0.4, 1.0])  # 6 of its 9 arguments


class Client:
    """An endpoint that sends raw messages to ``node`` and keeps what comes back."""

    def __init__(self, endpoint: UdpEndpoint, node: UdpEndpoint) -> None:
        self.endpoint, self.node = endpoint, node
        self.got: list[OscMessage] = []
        endpoint.set_handler(lambda message, _: self.got.append(message))

    def send(self, address: str, args: list[int | float | str]) -> None:
        self.endpoint.send_raw(address, args, self.node.local_address)

    async def answered(self, n: int) -> list[OscMessage]:
        await wait_for(lambda: len(self.got) >= n, 10.0)
        return self.got


async def _pair(role: str | None = None) -> tuple[UdpEndpoint, Client]:
    node = await UdpEndpoint.open("127.0.0.1", clock=lambda: 0.0, role=role)  # the reply budget never refills
    client = await UdpEndpoint.open("127.0.0.1")
    return node, Client(client, node)


def test_an_undecodable_control_message_is_answered_with_its_services_refusal() -> None:
    async def main() -> None:
        node, client = await _pair()
        try:
            client.send("/batteur/contact", [1, 2])  # a stream: never answered
            client.send("/batteur/physics/rejected", ["x"])  # a refusal: never answered
            client.send("/batteur/recogniser/hit", ["soon"])  # the recogniser has no refusal message
            client.send(*BAD_TARGET)
            client.send("/batteur/score/tempo", [-1.0])
            client.send("/batteur/sound/level", ["snare", "loud"])  # the instrument decoded: named
            client.send("/batteur/sound/level", ["sn@re", 3.0])  # not an instrument: none named
            client.send("/batteur/interaction/redundancy", [])
            client.send("/batteur/graphics/latency", ["soon"])
            got = await client.answered(6)
            await asyncio.sleep(0)
            assert node.stats.dropped_total == 9 and node.stats.messages_in == 0
            target, tempo, level, bad_name, redundancy, latency = got
            assert isinstance(target, PhysicsRejected) and target.address == "/batteur/physics/target"
            assert "wrong_arity" in target.reason and "expected 9 arguments, got 6" in target.reason
            assert isinstance(tempo, PhysicsRejected) and tempo.address == "/batteur/score/tempo"
            assert "out_of_range" in tempo.reason
            assert isinstance(level, SoundRejected) and level.address == "/batteur/sound/level"
            assert level.instrument == "snare" and "wrong_type" in level.reason
            assert isinstance(bad_name, SoundRejected) and bad_name.instrument == ""
            assert "out_of_range" in bad_name.reason or "wrong_type" in bad_name.reason
            assert isinstance(redundancy, InteractionError)
            assert redundancy.request == "/batteur/interaction/redundancy" and "wrong_arity" in redundancy.detail
            assert isinstance(latency, GraphicsRejected) and latency.address == "/batteur/graphics/latency"
            assert "wrong_type" in latency.reason
            client.send(*BAD_TARGET)  # the sentinel: once it is answered, nothing else came before it
            assert len(await client.answered(7)) == 7
        finally:
            client.endpoint.close()
            node.close()

    asyncio.run(main())


def test_a_flood_of_undecodable_controls_is_answered_within_the_senders_budget_and_the_rest_counted() -> None:
    async def main() -> None:
        node, client = await _pair()
        try:
            flood = 3 * int(DECODE_REPLY_BURST)
            for _ in range(flood):
                client.send(*BAD_TARGET)
            await wait_for(lambda: node.stats.dropped_total == flood, 10.0)
            assert len(await client.answered(int(DECODE_REPLY_BURST))) == DECODE_REPLY_BURST
            assert node.decode_unanswered == flood - DECODE_REPLY_BURST
        finally:
            client.endpoint.close()
            node.close()

    asyncio.run(main())


def test_only_known_control_addresses_have_a_refusal() -> None:
    assert decode_refusal("/batteur/pose", "wrong_arity") is None
    assert decode_refusal("/batteur/impact", "wrong_arity") is None
    assert decode_refusal("/batteur/nowhere", "unknown") is None
    assert decode_refusal("/batteur/interaction/error", "wrong_arity") is None
    long = decode_refusal("/batteur/physics/reset", "x" * 2000)
    assert isinstance(long, PhysicsRejected) and len(long.reason) == 512


BAD_TEMPO = ("/batteur/score/tempo", [-1.0])  # out of range: the physics node plays scores
BAD_LEVEL = ("/batteur/sound/level", ["snare", "loud"])
BAD_REDUNDANCY = ("/batteur/interaction/redundancy", [])


@pytest.mark.parametrize("role, own", [("sound", BAD_LEVEL), ("interaction", BAD_REDUNDANCY)])
def test_a_node_counts_a_misdirected_undecodable_control_and_answers_only_its_own(
        role: str, own: tuple[str, list[int | float | str]]) -> None:
    """A malformed physics or score control sent to a sound (interaction) node is dropped and counted, and not
    answered with /batteur/physics/rejected: that refusal speaks for physics, which never saw the message."""

    async def main() -> None:
        node, client = await _pair(role)
        try:
            client.send(*BAD_TARGET)
            client.send(*BAD_TEMPO)
            client.send(*own)  # the sentinel: once it is answered, nothing else came before it
            got = await client.answered(1)
            await asyncio.sleep(0)
            assert node.stats.dropped_total == 3 and node.stats.messages_in == 0
            assert [type(m) for m in got] == [SoundRejected if role == "sound" else InteractionError], got
        finally:
            client.endpoint.close()
            node.close()

    asyncio.run(main())


def test_the_physics_node_still_answers_a_malformed_physics_or_score_control() -> None:
    async def main() -> None:
        node, client = await _pair("physics")
        try:
            client.send(*BAD_LEVEL)  # sound's: counted, not answered
            client.send(*BAD_TARGET)
            client.send(*BAD_TEMPO)
            got = await client.answered(2)
            await asyncio.sleep(0)
            assert node.stats.dropped_total == 3
            assert [(type(m), getattr(m, "address", "")) for m in got] == [
                (PhysicsRejected, "/batteur/physics/target"), (PhysicsRejected, "/batteur/score/tempo")]
        finally:
            client.endpoint.close()
            node.close()

    asyncio.run(main())


def test_a_refusal_is_given_only_by_the_role_that_owns_the_address() -> None:
    assert isinstance(decode_refusal("/batteur/score/tempo", "out_of_range", role="physics"), PhysicsRejected)
    assert decode_refusal("/batteur/physics/reset", "wrong_arity", role="sound") is None
    assert decode_refusal("/batteur/score/tempo", "out_of_range", role="graphics") is None
    assert decode_refusal("/batteur/sound/level", "wrong_type", role="physics") is None
    assert isinstance(decode_refusal("/batteur/graphics/latency", "wrong_type", role="graphics"), GraphicsRejected)
    assert decode_refusal("/batteur/graphics/latency", "wrong_type", role="recogniser") is None


def test_a_sound_node_does_not_answer_a_malformed_physics_control() -> None:
    """The same through a real node (the runtime's Node with the sound role): counted, not answered for physics."""

    async def main() -> None:
        node = Node(NullCore(), load_settings({"role": "sound", "discovery": False,  # type: ignore[arg-type]
                                               "clock_master": "self", "oscquery": False}))
        await node.start()
        assert node.endpoint is not None
        client = Client(await UdpEndpoint.open("127.0.0.1"), node.endpoint)
        try:
            client.send(*BAD_TARGET)
            client.send(*BAD_LEVEL)  # the sentinel
            got = await client.answered(1)
            await asyncio.sleep(0)
            assert node.endpoint.stats.dropped_total == 2
            assert [type(m) for m in got] == [SoundRejected], got
        finally:
            client.endpoint.close()
            await node.stop()

    asyncio.run(main())
