"""A node says, once, when a peer's Health stops coming, and once when it is back.

A live-set walkthrough (7 Dec) killed graphics and sound mid-set and restarted each by its own command: the other
nodes' logs said nothing either time (``batteur ls`` still showed "peers 3"). Two in-process nodes on loopback with
static peers (no discovery), a short health interval; one is stopped and started again on its port.
"""

from __future__ import annotations

import asyncio
import logging

import pytest

from common.config import load_settings
from common.runtime import PEER_SILENT_HEALTHS, Node
from tests.ports import free_ports
from tests.test_runtime import EchoCore
from tests.waiting import wait_for

pytestmark = pytest.mark.timeout(120)

INTERVAL_S = 0.2
"""The nodes' health interval, seconds: a peer is silent after :data:`PEER_SILENT_HEALTHS` of them."""


def node(role: str, port: int, peer: str, node_id: str = "") -> Node:
    """A node of ``role`` on loopback ``port`` with the static ``peer`` (ROLE=HOST:PORT), id ``node_id`` (default
    ROLE-1), Health every :data:`INTERVAL_S`."""
    return Node(EchoCore(rate_hz=0.0), load_settings({"role": role, "node_id": node_id or f"{role}-1", "port": port,
                                                      "discovery": False, "peers": [peer], "oscquery": False}),
                health_interval_s=INTERVAL_S, clock_wait_s=0.2)


async def started_pair(sound_port: int, graphics_port: int) -> tuple[Node, Node]:
    """A sound and a graphics node (sound-1, graphics-1), each the other's static peer, started."""
    sound = node("sound", sound_port, f"graphics=127.0.0.1:{graphics_port}")
    graphics = node("graphics", graphics_port, f"sound=127.0.0.1:{sound_port}")
    await sound.start()
    await graphics.start()
    return sound, graphics


def said(caplog: pytest.LogCaptureFixture, text: str) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name == "batteur.runtime" and text in r.getMessage()]


def test_a_peer_that_stops_is_said_to_once_and_again_when_it_is_back(caplog: pytest.LogCaptureFixture) -> None:
    sound_port, graphics_port = free_ports(2)

    async def main() -> None:
        sound, graphics = await started_pair(sound_port, graphics_port)
        try:
            await wait_for(lambda: "graphics-1" in sound.peer_health, timeout=60)
            assert not said(caplog, "stopped answering")  # answering all along
            await graphics.stop()  # killed mid-set
            await wait_for(lambda: bool(said(caplog, "graphics graphics-1 at ")), timeout=60)
            await asyncio.sleep(3 * PEER_SILENT_HEALTHS * INTERVAL_S)  # more intervals without it: said once only
            again = node("graphics", graphics_port, f"sound=127.0.0.1:{sound_port}")  # restarted by its command
            await again.start()
            try:
                await wait_for(lambda: bool(said(caplog, "answers again")), timeout=60)
            finally:
                await again.stop()
        finally:
            await sound.stop()

    with caplog.at_level(logging.INFO, logger="batteur.runtime"):
        asyncio.run(main())
    stopped = said(caplog, "stopped answering")
    assert len(stopped) == 1, stopped
    assert stopped[0].startswith(f"peer graphics graphics-1 at 127.0.0.1:{graphics_port} stopped answering: no "
                                 "Health for "), stopped
    assert said(caplog, "answers again") == [f"peer graphics graphics-1 at 127.0.0.1:{graphics_port} answers again"]
