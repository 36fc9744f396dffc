"""A message to a role no peer of which is known is not sent, and that is said: a warning naming the role and what
to do (``--peer ROLE=HOST:PORT``, start that node, discovery's interfaces), at most once a minute per role (and
not in the first seconds, while a rig's nodes are still finding each other), and
counted in the node's Health (``unroutable``), which ``batteur ls --json`` shows. Until 7 Dec it was a DEBUG line
only: a rig without a sound node playing ``--score demo`` logged "9 impacts" and nothing else.

Endpoints run in-process on loopback with an injected clock (no discovery, nothing sent anywhere).
"""

from __future__ import annotations

import asyncio
import json
import logging
from collections.abc import Iterator

import pytest

import common.transport
from batteur.tools import ls
from common.config import load_settings
from common.core import Outgoing
from common.messages import Health, Hello, Impact, OscMessage, encode
from common.peers import Peer, PeerTable
from common.runtime import Node
from common.transport import NO_PEER_GRACE_S, NO_PEER_LOG_INTERVAL_S, UdpEndpoint
from tests.health_answerer import HealthAnswerer
from tests.null_core import NullCore
from tests.test_health_unanswered import health_after
from tests.waiting import wait_for

pytestmark = pytest.mark.timeout(120)

HELLO = Hello(role="physics", node_id="physics-1", protocol=1, osc_port=9)
IMPACT = Impact(seq=1, time=2.5, instrument="snare", zone="centre", r=0.25, theta=0.5, velocity=3.0,
                impulse=0.0625, peak_force=120.0, duration=0.00390625, part="right_stick_tip")


class _Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def _no_peer_lines(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [r.getMessage() for r in caplog.records
            if r.name == "batteur.transport" and r.levelno == logging.WARNING and "peer" in r.getMessage()]


def test_a_role_without_peers_is_warned_about_once_clearly_then_at_most_once_a_minute(
        caplog: pytest.LogCaptureFixture) -> None:
    async def main() -> None:
        clock = _Clock()
        peers = PeerTable()
        endpoint = await UdpEndpoint.open(peers=peers, clock=clock)
        try:
            endpoint.send(IMPACT, "sound")  # at start: the rig's other nodes may not be found yet
            clock.now += NO_PEER_GRACE_S - 0.5
            endpoint.send(IMPACT, "sound")
            assert _no_peer_lines(caplog) == [] and endpoint.unroutable == 2  # counted, not said
            clock.now += 0.5
            for _ in range(9):  # interaction's "9 impacts", with no sound node
                endpoint.send(IMPACT, "sound")
            first = _no_peer_lines(caplog)
            assert len(first) == 1, first
            assert "sound" in first[0] and "--peer sound=HOST:PORT" in first[0]
            assert "--interface" in first[0] and "on purpose" in first[0]  # what to do, or that it may be meant
            assert endpoint.unroutable == 2 + 9
            # graphics never started: 60 poses a second for ten minutes are ten lines, each with its count
            for _ in range(10):
                clock.now += NO_PEER_LOG_INTERVAL_S / 60
                for _ in range(59):
                    endpoint.send(HELLO, "graphics")
                    clock.now += 1.0
            lines = _no_peer_lines(caplog)[1:]
            graphics = [line for line in lines if "graphics" in line]
            assert len(graphics) == 10 and len(lines) == len(graphics), lines  # one a minute, not 590
            assert "--peer graphics=HOST:PORT" in graphics[0]  # its own first warning is the full one
            assert all("--peer" not in line and "more since the last report" in line for line in graphics[1:])
            # sound is still missing: said again once its interval has passed, with what was held back
            endpoint.send(IMPACT, "sound")
            again = [line for line in _no_peer_lines(caplog) if "sound" in line][1:]
            assert len(again) == 1 and "still no sound peer" in again[0] and "+8 more" in again[0]
            # once a peer is known, nothing more is said
            peers.add(Peer(role="sound", host="127.0.0.1", port=9, node_id="sound-1"))
            count = len(_no_peer_lines(caplog))
            clock.now += 10 * NO_PEER_LOG_INTERVAL_S
            endpoint.send(IMPACT, "sound")
            assert len(_no_peer_lines(caplog)) == count and endpoint.unroutable == 2 + 9 + 590 + 1
        finally:
            endpoint.close()

    with caplog.at_level(logging.INFO, logger="batteur.transport"):
        asyncio.run(main())


class _SendsToGraphics(NullCore):
    """Answers every message but a Hello with a message to graphics (which no peer is)."""

    def handle(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        return [] if isinstance(message, Hello) else [Outgoing(HELLO, "graphics")]


class _SendsToGraphicsAndSound(NullCore):
    """Answers every message but a Hello with a message to graphics and one to sound (no peer is either)."""

    def handle(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        return [] if isinstance(message, Hello) else [Outgoing(HELLO, "graphics"), Outgoing(IMPACT, "sound")]


@pytest.mark.parametrize("absent", [[], ["graphics"]], ids=["alone", "absent-graphics"])
def test_a_role_left_out_on_purpose_is_counted_not_warned_about(absent: list[str], caplog: pytest.LogCaptureFixture,
                                                                monkeypatch: pytest.MonkeyPatch) -> None:
    """``--absent graphics`` (what ``batteur rig --services physics,interaction,sound`` gives its services): no
    "no graphics peer known" once and then once a minute for a role the rig did not start; the messages are still
    counted, and a role missing otherwise is still warned about. A node started alone warns about graphics too."""
    monkeypatch.setattr(common.transport, "NO_PEER_GRACE_S", 0.0)  # not the 10 s a rig's nodes get to be found

    async def main() -> None:
        node = Node(_SendsToGraphicsAndSound(), load_settings(  # type: ignore[arg-type]
            {"role": "physics", "discovery": False, "clock_master": "self", "oscquery": False, "absent": absent}))
        await node.start()
        assert node.endpoint is not None
        client = await UdpEndpoint.open("127.0.0.1")
        try:
            for _ in range(3):
                client.send(IMPACT, node.endpoint.local_address)
            await wait_for(lambda: node.endpoint is not None and node.endpoint.unroutable == 6, 20.0)
        finally:
            client.close()
            await node.stop()

    with caplog.at_level(logging.INFO, logger="batteur.transport"):
        asyncio.run(main())
    lines = _no_peer_lines(caplog)
    said = [line for line in lines if "no graphics peer" in line]
    assert len(said) == (0 if absent else 1), lines
    sound = [line for line in lines if "no sound peer" in line]
    assert len(sound) == 1 and "--absent sound" in sound[0], lines  # how to say it is meant


def test_a_nodes_health_counts_what_it_could_not_send() -> None:
    health, _ = asyncio.run(health_after(_SendsToGraphics(), "sound", [IMPACT, IMPACT, IMPACT]))
    assert health.unroutable == 3


@pytest.fixture
def node_port() -> Iterator[int]:
    """A UDP "node" on loopback that answers every Hello with a Health of 7 unroutable messages."""
    health = Health(node_id="interaction-1", role="interaction", protocol=1, time=3.0, rate_hz=0.0,
                    target_rate_hz=0.0, overruns=0, messages_in=1, messages_out=2, dropped=0, dropped_malformed=0,
                    dropped_unknown=0, dropped_type=0, dropped_range=0, dropped_other=0, late=0, peers=1,
                    unroutable=7)
    node = HealthAnswerer(encode(health))
    yield node.port
    node.close()


def test_ls_json_shows_the_unroutable_count(node_port: int, capsys: pytest.CaptureFixture[str]) -> None:
    assert ls.main(["--node", f"127.0.0.1:{node_port}", "--timeout", "3", "--json"]) == 0
    row = json.loads(capsys.readouterr().out)[0]
    assert (row["status"], row["unroutable"]) == ("ok", 7)
