"""A peer said to have stopped answering: not said of one discovery dropped (its goodbye), and said back when it
answers again under another node id, restarted by its own command.

Review of 6c221a4 (7 Dec): a node logs once when a peer's Health stops coming and once when it is back
(tests/test_peer_silent.py). A peer that left on purpose, which discovery already says ("discovery: lost ... (said
goodbye)"), was then warned of as well, "stopped answering ... (stopped, or restarting?)", its Health kept for good.
And a peer restarted by its own command without the rig's --node-id gets a new id (``role-host-pid``): it was
never said to be back, its old id left silent for good. Two in-process nodes on loopback with static peers (no
discovery); a discovered peer and its removal are the peer table's, as discovery makes them.
"""

from __future__ import annotations

import asyncio
import logging
import time

import pytest

from common.peers import Peer
from tests.ports import free_ports
from tests.test_peer_silent import node, said, started_pair
from tests.waiting import wait_for

pytestmark = pytest.mark.timeout(120)


def test_a_peer_that_said_goodbye_is_not_said_to_have_stopped_answering(caplog: pytest.LogCaptureFixture) -> None:
    sound_port, graphics_port = free_ports(2)

    async def main() -> None:
        sound, graphics = await started_pair(sound_port, graphics_port)
        try:
            sound.peers.add(Peer("graphics", "127.0.0.1", graphics_port, node_id="graphics-1"))  # as discovered
            await wait_for(lambda: "graphics-1" in sound.peer_health, timeout=60)
            await graphics.stop()
            sound.peers.remove("graphics-1")  # discovery: its goodbye
            assert "graphics-1" not in sound.peer_health
            sound._note_silent_peers(time.monotonic() + 3600.0)  # long after: nothing to say of it
        finally:
            await sound.stop()

    with caplog.at_level(logging.INFO, logger="batteur.runtime"):
        asyncio.run(main())
    assert not said(caplog, "stopped answering")


def test_a_peer_restarted_under_another_node_id_is_said_to_be_back(caplog: pytest.LogCaptureFixture) -> None:
    sound_port, graphics_port = free_ports(2)

    async def main() -> None:
        sound, graphics = await started_pair(sound_port, graphics_port)
        try:
            await wait_for(lambda: "graphics-1" in sound.peer_health, timeout=60)
            await graphics.stop()  # killed mid-set
            await wait_for(lambda: bool(said(caplog, "stopped answering")), timeout=60)
            # restarted by its own command: its port, its default id (role-host-pid), here graphics-2
            again = node("graphics", graphics_port, f"sound=127.0.0.1:{sound_port}", node_id="graphics-2")
            await again.start()
            try:
                await wait_for(lambda: bool(said(caplog, "answers again")), timeout=60)
            finally:
                await again.stop()
            assert "graphics-1" not in sound.peer_health and not sound.silent_peers  # forgotten: the same node
        finally:
            await sound.stop()

    with caplog.at_level(logging.INFO, logger="batteur.runtime"):
        asyncio.run(main())
    assert said(caplog, "answers again") == [
        f"peer graphics graphics-1 at 127.0.0.1:{graphics_port} answers again, restarted as graphics-2"]
