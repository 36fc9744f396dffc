"""``/batteur/clock/status``: the clock estimate's figures and counters, published beside Health by every node
whose clock master is another node, and printed by ``batteur echo`` in one line (loopback only)."""

from __future__ import annotations

import asyncio
import json
import re
import threading
import time
from collections.abc import Iterator

import pytest

from batteur.tools import echo
from common.config import load_settings
from common.messages import REGISTRY, ClockStatus, Health, OscMessage, decode, encode
from common.runtime import Node
from common.transport import UdpEndpoint
from tests.test_runtime import EchoCore
from tests.waiting import wait_for

pytestmark = pytest.mark.timeout(60)


def _status(**changes: object) -> ClockStatus:
    fields: dict[str, object] = dict(node_id="sound-lap-42", synced=1, offset_s=10.000123, uncertainty_s=0.000045,
                                     round_trip_s=0.00021, samples=32, rejected=3, outliers=2, steps=1,
                                     foreign_pongs=5, master="physics-rig-7")
    return ClockStatus.model_validate({**fields, **changes})


def test_the_status_is_a_registered_message_that_round_trips() -> None:
    assert REGISTRY.get("/batteur/clock/status") is ClockStatus
    status = _status()
    back = decode(encode(status)).messages[0]
    assert isinstance(back, ClockStatus)
    assert (back.node_id, back.synced, back.samples, back.rejected, back.outliers, back.steps, back.foreign_pongs,
            back.master) == ("sound-lap-42", 1, 32, 3, 2, 1, 5, "physics-rig-7")
    assert back.offset_s == pytest.approx(10.000123, abs=1e-6)
    assert back.uncertainty_s == pytest.approx(0.000045, rel=1e-6)
    # before any sample there is no figure to give: -1, and no master yet: ''
    empty = _status(synced=0, offset_s=0.0, uncertainty_s=-1.0, round_trip_s=-1.0, samples=0, master="")
    assert decode(encode(empty)).messages[0] == empty


def test_echo_prints_the_status_in_one_readable_line() -> None:
    line = echo.format_message(_status(), as_json=False)
    assert line == ("/batteur/clock/status sound-lap-42 synced (master physics-rig-7): offset +10.000123 s "
                    "+/- 0.000045 s, best round trip 0.000210 s, 32 samples, 3 rejected (2 outliers), 1 steps, "
                    "5 foreign pongs")
    waiting = echo.format_message(_status(synced=0, offset_s=0.0, uncertainty_s=-1.0, round_trip_s=-1.0,
                                          samples=0, rejected=0, outliers=0, steps=0, foreign_pongs=0, master=""),
                                  as_json=False)
    assert waiting == ("/batteur/clock/status sound-lap-42 not synced (master none found): offset +0.000000 s, "
                       "no estimate yet, 0 samples, 0 rejected (0 outliers), 0 steps, 0 foreign pongs")
    assert "\n" not in line
    # --json keeps the fields as they are
    assert json.loads(echo.format_message(_status(), as_json=True)) == {"address": "/batteur/clock/status",
                                                                       **_status().model_dump(mode="json")}


async def _rig(listener: UdpEndpoint, health_interval_s: float) -> tuple[Node, Node]:
    """A clock master (physics) and a sound node, both with ``listener`` as a graphics peer."""
    epoch = time.time() - 1000.0
    graphics = f"graphics={listener.local_address}"
    master = Node(EchoCore(rate_hz=0.0), load_settings({"role": "physics", "discovery": False, "epoch": epoch,
                                                        "peers": [graphics]}), health_interval_s=health_interval_s)
    await master.start()
    assert master.endpoint is not None
    remote = Node(EchoCore(rate_hz=0.0), load_settings({
        "role": "sound", "discovery": False, "epoch": epoch + 10.0,
        "peers": [f"physics={master.endpoint.local_address}", graphics]}),
        ping_interval_s=0.05, health_interval_s=health_interval_s)
    await remote.start()
    return master, remote


def test_a_synced_node_publishes_its_clock_status_to_its_peers_and_the_master_does_not() -> None:
    async def main() -> None:
        listener = await UdpEndpoint.open("127.0.0.1", 0)
        got: list[tuple[OscMessage, str]] = []
        listener.set_handler(lambda message, source: got.append((message, source)))
        master, remote = await _rig(listener, health_interval_s=0.1)
        try:
            assert master.endpoint is not None and remote.endpoint is not None
            mine, masters = remote.endpoint.local_address, master.endpoint.local_address

            def statuses() -> list[ClockStatus]:
                return [m for m, s in got if isinstance(m, ClockStatus) and s == mine]

            await wait_for(lambda: any(s.synced and s.samples >= 8 for s in statuses()))
            status = next(s for s in statuses() if s.synced and s.samples >= 8)
            assert status.node_id == remote.node_id and status.master == f"static:physics:{masters}"
            assert status.offset_s == pytest.approx(10.0, abs=0.005)
            assert 0.0 <= status.uncertainty_s < 0.005 and 0.0 <= status.round_trip_s < 1.0
            assert (status.rejected, status.outliers, status.steps, status.foreign_pongs) == (0, 0, 0, 0)
            # the master sends Health, never a status (its clock is the rig clock)
            await wait_for(lambda: sum(isinstance(m, Health) and s == masters for m, s in got) >= 3)
            assert not [m for m, s in got if isinstance(m, ClockStatus) and s == masters]
            # each status goes with a Health to the same peer: as many of one as of the other
            healths = [m for m, s in got if isinstance(m, Health) and s == mine]
            assert abs(len(healths) - len(statuses())) <= 1
        finally:
            await remote.stop()
            await master.stop()
            listener.close()

    asyncio.run(main())


def test_a_node_without_its_master_says_so() -> None:
    async def main() -> None:
        listener = await UdpEndpoint.open("127.0.0.1", 0)
        got: list[OscMessage] = []
        listener.set_handler(lambda message, source: got.append(message))
        remote = Node(EchoCore(rate_hz=0.0), load_settings({
            "role": "sound", "discovery": False, "peers": [f"graphics={listener.local_address}"]}),
            health_interval_s=0.1, clock_wait_s=60.0)
        await remote.start()
        try:
            await wait_for(lambda: any(isinstance(m, ClockStatus) for m in got))
            status = next(m for m in got if isinstance(m, ClockStatus))
            assert status == ClockStatus(node_id=remote.node_id, synced=0, offset_s=0.0, uncertainty_s=-1.0,
                                         round_trip_s=-1.0, samples=0, rejected=0, outliers=0, steps=0,
                                         foreign_pongs=0, master="")
        finally:
            await remote.stop()
            listener.close()

    asyncio.run(main())


@pytest.fixture
def synced_sound_node() -> Iterator[Node]:
    """A sound node synced to a physics master, both in a thread of their own (echo runs its loop in this one)."""
    ready = threading.Event()
    stop = threading.Event()
    holder: list[Node] = []

    async def serve() -> None:
        listener = await UdpEndpoint.open("127.0.0.1", 0)
        master, remote = await _rig(listener, health_interval_s=0.2)
        holder.append(remote)
        await wait_for(lambda: remote.clock.synced)
        ready.set()
        while not stop.is_set():
            await asyncio.sleep(0.02)
        await remote.stop()
        await master.stop()
        listener.close()

    thread = threading.Thread(target=asyncio.run, args=(serve(),), daemon=True)
    thread.start()
    assert ready.wait(10)
    yield holder[0]
    stop.set()
    thread.join(10)


def test_batteur_echo_prints_a_live_nodes_clock_status(synced_sound_node: Node,
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    assert synced_sound_node.endpoint is not None
    address = synced_sound_node.endpoint.local_address
    assert echo.main(["/batteur/clock/status", "--node", address, "--count", "1", "--duration", "20"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 1
    found = re.match(rf"/batteur/clock/status {synced_sound_node.node_id} synced "
                     r"\(master static:physics:127\.0\.0\.1:\d+\): offset (\S+)", lines[0])
    assert found, lines[0]
    assert float(found[1]) == pytest.approx(10.0, abs=0.005)
    assert lines[0].endswith("0 foreign pongs")
