"""A node takes clock pongs only from the address it pings its clock master at (loopback, two sockets).

A host that sees the pings (same LAN, same Wi-Fi) can answer them before the master does, echoing
node id, sequence number and send time, so the estimator's own checks pass; four such answers in a
row that agree with each other look like the master's clock moving, and the estimate followed them.
"""

from __future__ import annotations

import asyncio
import time

import pytest

from common.config import load_settings
from common.messages import PROTOCOL_VERSION, ClockPong, DropReason, Health, Hello, OscMessage
from common.peers import Peer
from common.runtime import Node
from common.transport import UdpEndpoint
from tests.test_clock_qa import assert_far_pong_from_master_ignored
from tests.test_runtime import EchoCore
from tests.waiting import wait_for

pytestmark = pytest.mark.timeout(60)


async def _master_and_remote(peer: str | None = "127.0.0.1:{port}") -> tuple[Node, Node]:
    """A clock master (physics) and a sound node pinging it every 50 ms, their epochs 10 s apart.

    ``peer``: how the sound node is told where the master is (``{port}``: the master's), None: not told.
    """
    epoch = time.time() - 1000.0
    master = Node(EchoCore(rate_hz=0.0), load_settings({"role": "physics", "discovery": False, "epoch": epoch}))
    await master.start()
    assert master.endpoint is not None
    peers = [] if peer is None else ["physics=" + peer.format(port=master.endpoint.port)]
    remote = Node(EchoCore(rate_hz=0.0), load_settings({
        "role": "sound", "discovery": False, "epoch": epoch + 10.0, "peers": peers}), ping_interval_s=0.05)
    await remote.start()
    return master, remote


async def _forge(remote: Node, forger: UdpEndpoint, shift_s: float, count: int) -> None:
    """Answer ``count`` of the remote's pings from ``forger`` as a master ``shift_s`` seconds ahead would,
    faster than the real one; return once the remote has handled them all."""
    assert remote.endpoint is not None
    to = remote.endpoint.local_address
    for _ in range(count):
        ping = remote.estimator.make_ping(remote.clock.local_now())  # as copied off the wire
        t = ping.t_send + remote.clock.offset + shift_s
        forger.send(ClockPong(node_id=ping.node_id, seq=ping.seq, t_send=ping.t_send, t_receive=t, t_reply=t), to)
    # datagrams from one socket to another are handled in order: the Health answering this Hello comes after
    answered: list[OscMessage] = []
    forger.set_handler(lambda message, source: answered.append(message))
    forger.send(Hello(role="forger", node_id="forger", protocol=PROTOCOL_VERSION, osc_port=forger.port), to)
    await wait_for(lambda: any(isinstance(m, Health) for m in answered))


def test_pongs_from_another_address_do_not_move_the_rig_clock() -> None:
    async def main() -> None:
        master, remote = await _master_and_remote()
        forger = await UdpEndpoint.open("127.0.0.1", 0)
        try:
            await wait_for(lambda: len(remote.estimator.samples) >= 8)
            remote.ping_interval_s = 3600.0  # the forger's answers then come in a row, as on a quiet network
            assert remote.endpoint is not None
            before = remote.clock.offset
            refused = remote.endpoint.stats.dropped[DropReason.NOT_ALLOWED]
            await _forge(remote, forger, shift_s=1.0, count=8)
            assert remote.clock.offset == pytest.approx(before, abs=0.005)
            assert remote.estimator.steps == 0
            assert remote.endpoint.stats.dropped[DropReason.NOT_ALLOWED] - refused == 8
            assert remote.clock_status().foreign_pongs == 8
        finally:
            forger.close()
            await remote.stop()
            await master.stop()

    asyncio.run(main())


def test_a_master_learnt_at_run_time_is_answered_from_its_own_address_only() -> None:
    """As with zeroconf: no --peer; the master's address comes into the peer table while the node runs."""

    async def main() -> None:
        master, remote = await _master_and_remote(peer=None)
        forger = await UdpEndpoint.open("127.0.0.1", 0)
        try:
            assert master.endpoint is not None and remote.endpoint is not None
            # before any master is known, nobody is pinged: a pong is nobody's answer
            await _forge(remote, forger, shift_s=0.0, count=1)
            assert not remote.clock.synced and remote.endpoint.stats.dropped[DropReason.NOT_ALLOWED] == 1
            remote.peers.add(Peer(role="physics", host="127.0.0.1", port=master.endpoint.port,
                                  node_id=master.node_id))  # what discovery does when it finds the master
            await wait_for(lambda: len(remote.estimator.samples) >= 8)
            assert remote.clock.now() == pytest.approx(master.clock.now(), abs=0.005)
            remote.ping_interval_s = 3600.0
            before = remote.clock.offset
            await _forge(remote, forger, shift_s=1.0, count=8)
            assert remote.clock.offset == pytest.approx(before, abs=0.005)
            assert remote.endpoint.stats.dropped[DropReason.NOT_ALLOWED] == 9
        finally:
            forger.close()
            await remote.stop()
            await master.stop()

    asyncio.run(main())


def test_a_master_given_by_host_name_still_syncs() -> None:
    """``--peer physics=localhost:PORT``: pongs come from the address the name resolves to."""

    async def main() -> None:
        master, remote = await _master_and_remote(peer="localhost:{port}")
        try:
            await wait_for(lambda: len(remote.estimator.samples) >= 4)
            assert remote.clock.offset == pytest.approx(10.0, abs=0.005)
            assert remote.clock_status().foreign_pongs == 0
        finally:
            await remote.stop()
            await master.stop()

    asyncio.run(main())


def test_the_estimator_still_rejects_a_forged_pong_from_the_masters_address() -> None:
    """The second line of defence: a pong that does come from the master's address but claims a clock
    an hour away is an outlier (the master's socket cannot be spoofed on loopback; injected here)."""

    async def main() -> None:
        master, remote = await _master_and_remote()
        try:
            await wait_for(lambda: len(remote.estimator.samples) >= 8)
            assert_far_pong_from_master_ignored(master, remote)
            assert remote.endpoint is not None and remote.endpoint.stats.dropped[DropReason.NOT_ALLOWED] == 0
        finally:
            await remote.stop()
            await master.stop()

    asyncio.run(main())
