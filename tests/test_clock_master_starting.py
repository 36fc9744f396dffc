"""A node whose clock master is a known peer that does not answer yet (physics still building its scene, as in
``batteur rig`` on a loaded machine) says so at INFO and starts on its own clock; it warns only when the master
stays silent for :data:`~common.runtime.MASTER_SILENT_WARN_S`. A node that knows no master at all warns at once,
as before. A node that finds its master by discovery alone (no ``--peer`` for its role: ``batteur rig
--no-static-peers``; physics registers only once its scene is built) says so at INFO too and warns after
:data:`~common.runtime.MASTER_SILENT_WARN_S`; one with neither discovery nor a ``--peer`` for the master's role has
no way to find one, and its warning says why, at once. Discovery is a stand-in that finds nothing (no zeroconf)."""

from __future__ import annotations

import asyncio
import logging

import pytest

from common import runtime
from common.config import load_settings
from common.peers import Peer
from common.runtime import Node
from tests.ports import free_port
from tests.test_runtime import EchoCore, FakeDiscovery
from tests.waiting import wait_for

pytestmark = pytest.mark.timeout(60)


def run_waiting_node(peers: list[str], caplog: pytest.LogCaptureFixture, until_s: float,
                     discovery: bool = False) -> Node:
    """A sound node whose master is physics (``peers``: where it is, if anywhere; ``discovery``: browsing with a
    discovery that finds nothing), run ``until_s`` seconds after its core started."""
    async def main() -> Node:
        node = Node(EchoCore(rate_hz=0.0), load_settings({"role": "sound", "discovery": discovery,
                                                          "clock_master": "physics", "peers": peers,
                                                          "oscquery": False}),
                    clock_wait_s=0.2, discovery_factory=lambda **kwargs: FakeDiscovery([], **kwargs))
        await node.start()
        try:
            await wait_for(lambda: node.core_started)
            await asyncio.sleep(until_s)
        finally:
            await node.stop()
        return node

    with caplog.at_level(logging.INFO, logger="batteur.runtime"):
        return asyncio.run(main())


def runtime_records(caplog: pytest.LogCaptureFixture, level: int) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name == "batteur.runtime" and r.levelno == level]


def test_a_master_still_starting_is_not_warned_about(caplog: pytest.LogCaptureFixture) -> None:
    # three "no clock master (physics) within 3 s ... rig time will jump" warnings while the rig waited for physics
    port = free_port()
    node = run_waiting_node([f"physics=127.0.0.1:{port}"], caplog, until_s=0.3)
    assert node.core_started and not node.clock.synced  # started on its own clock all the same
    assert runtime_records(caplog, logging.WARNING) == []
    said = [m for m in runtime_records(caplog, logging.INFO) if "has not answered" in m]
    assert said == [f"clock master physics at 127.0.0.1:{port} has not answered within 0.2 s (still starting?): "
                    "starting on this node's own clock, which follows the master's once it answers"]


def test_a_master_silent_for_long_is_warned_about(caplog: pytest.LogCaptureFixture,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(runtime, "MASTER_SILENT_WARN_S", 0.5)
    port = free_port()
    run_waiting_node([f"physics=127.0.0.1:{port}"], caplog, until_s=1.0)
    assert runtime_records(caplog, logging.WARNING) == [
        f"no answer from the clock master physics at 127.0.0.1:{port} within 0.5 s (is it running?): rig time is "
        "this node's own clock until it answers"]


def test_no_master_at_all_is_warned_about_at_once(caplog: pytest.LogCaptureFixture) -> None:
    run_waiting_node([], caplog, until_s=0.0)
    warnings = runtime_records(caplog, logging.WARNING)
    assert len(warnings) == 1 and warnings[0].startswith("no clock master (physics) within 0.2 s")


def test_a_master_not_yet_found_by_discovery_is_not_warned_about(caplog: pytest.LogCaptureFixture) -> None:
    node = run_waiting_node([], caplog, until_s=0.3, discovery=True)
    assert node.core_started and not node.clock.synced  # started on its own clock all the same
    assert runtime_records(caplog, logging.WARNING) == []
    assert [m for m in runtime_records(caplog, logging.INFO) if "by discovery" in m] == [
        "clock master (physics) not found by discovery within 0.2 s (still starting?): starting on this node's own "
        "clock, which follows the master's once it is found"]


def test_a_master_discovery_never_finds_is_warned_about_later(caplog: pytest.LogCaptureFixture,
                                                              monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(runtime, "MASTER_SILENT_WARN_S", 0.5)
    run_waiting_node([], caplog, until_s=1.0, discovery=True)
    assert runtime_records(caplog, logging.WARNING) == [
        "no clock master (physics) found by discovery within 0.5 s (is it running, on an interface this node "
        "browses?): rig time is this node's own clock and will jump when the master appears"]


def test_a_node_with_no_way_to_find_its_master_says_why(caplog: pytest.LogCaptureFixture,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(runtime, "MASTER_SILENT_WARN_S", 0.5)
    run_waiting_node([], caplog, until_s=1.0)
    assert runtime_records(caplog, logging.WARNING) == [
        "no clock master (physics) within 0.2 s, and no way to find one: discovery is off and no --peer names a "
        "physics node: starting on this node's own clock for good"]  # once: nothing more to wait for




def test_a_master_greeting_a_node_with_no_way_to_find_it_does_not_become_its_master() -> None:
    """What makes that warning's "for good" true: a Hello from the master (it has a ``--peer`` for this node) is
    answered, but makes no peer, so nothing is pinged and the clock stays this node's own (the docstring of
    ``_start_without_master`` said until 7 Dec that the master is found if it greets this node)."""
    async def main() -> tuple[bool, bool, bool]:
        sound = Node(EchoCore(rate_hz=0.0), load_settings({"role": "sound", "discovery": False, "clock_master":
                                                           "physics", "peers": [], "oscquery": False,
                                                           "host": "127.0.0.1", "port": free_port()}),
                     clock_wait_s=0.2)
        await sound.start()
        assert sound.endpoint is not None
        physics = Node(EchoCore(rate_hz=0.0), load_settings({
            "role": "physics", "discovery": False, "clock_master": "physics", "oscquery": False,
            "host": "127.0.0.1", "port": free_port(), "peers": [f"sound=127.0.0.1:{sound.endpoint.port}"]}))
        try:
            await wait_for(lambda: sound.core_started)  # the warning is out
            await physics.start()  # greets its static peer, the sound node
            await wait_for(lambda: sound.node_id in physics.peer_health)  # the Hello was answered
            return sound.clock_master_peer() is None, sound.clock.synced, physics.is_clock_master
        finally:
            await physics.stop()
            await sound.stop()

    no_master, synced, physics_is_master = asyncio.run(main())
    assert physics_is_master and no_master and not synced


def test_a_master_discovery_finds_late_but_silent_is_warned_about_by_address(
        caplog: pytest.LogCaptureFixture, monkeypatch: pytest.MonkeyPatch) -> None:
    """Discovery finds the master after the core started on this node's own clock, and it never answers: the
    warning names it and where it is, as for a ``--peer`` master that stays silent."""
    monkeypatch.setattr(runtime, "MASTER_SILENT_WARN_S", 0.5)
    port = free_port()

    async def main() -> None:
        node = Node(EchoCore(rate_hz=0.0), load_settings({"role": "sound", "discovery": True,
                                                          "clock_master": "physics", "peers": [],
                                                          "oscquery": False}),
                    clock_wait_s=0.2, discovery_factory=lambda **kwargs: FakeDiscovery([], **kwargs))
        await node.start()
        try:
            await wait_for(lambda: node.core_started)
            node.peers.add(Peer("physics", "127.0.0.1", port, node_id="physics-late"))  # as discovery would
            await wait_for(lambda: bool(runtime_records(caplog, logging.WARNING)))
        finally:
            await node.stop()

    with caplog.at_level(logging.INFO, logger="batteur.runtime"):
        asyncio.run(main())
    assert runtime_records(caplog, logging.WARNING) == [
        f"no answer from the clock master physics at 127.0.0.1:{port} within 0.5 s (is it running?): rig time is "
        "this node's own clock until it answers"]
