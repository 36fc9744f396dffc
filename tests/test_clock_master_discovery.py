"""A node that finds its clock master by discovery alone (no ``--peer`` for its role: ``batteur rig
--no-static-peers``) does not know it before it registers, seconds after its start for physics (it builds its
scene first). Until 6 Dec night such a node warned at 3 s "no clock master (physics) ... rig time will jump" on
every rig start; it now says so at INFO, and warns only when discovery has found no master after
:data:`~common.runtime.MASTER_SILENT_WARN_S`. A node with neither discovery nor a ``--peer`` for the master's role
has no way to find one: its warning says why, at once.

The discovery is a stand-in that finds nothing (no zeroconf), the nodes in-process on loopback.
"""

from __future__ import annotations

import asyncio
import logging

import pytest

from common import runtime
from common.config import load_settings
from common.runtime import Node
from tests.test_runtime import EchoCore, FakeDiscovery
from tests.waiting import wait_for

pytestmark = pytest.mark.timeout(60)


def run_node(discovery: bool, caplog: pytest.LogCaptureFixture, until_s: float) -> Node:
    """A sound node whose master is physics, with a discovery that finds nothing (or none), no ``--peer``; run
    ``until_s`` seconds after its core started."""
    async def main() -> Node:
        node = Node(EchoCore(rate_hz=0.0), load_settings({"role": "sound", "discovery": discovery,
                                                          "clock_master": "physics", "oscquery": False}),
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


def said(caplog: pytest.LogCaptureFixture, level: int) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name == "batteur.runtime" and r.levelno == level]


def test_a_master_not_yet_found_by_discovery_is_not_warned_about(caplog: pytest.LogCaptureFixture) -> None:
    node = run_node(True, caplog, until_s=0.3)
    assert node.core_started and not node.clock.synced  # started on its own clock all the same
    assert said(caplog, logging.WARNING) == []
    assert [m for m in said(caplog, logging.INFO) if "by discovery" in m] == [
        "clock master (physics) not found by discovery within 0.2 s (still starting?): starting on this node's own "
        "clock, which follows the master's once it is found"]


def test_a_master_discovery_never_finds_is_warned_about_later(caplog: pytest.LogCaptureFixture,
                                                              monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(runtime, "MASTER_SILENT_WARN_S", 0.5)
    run_node(True, caplog, until_s=1.0)
    assert said(caplog, logging.WARNING) == [
        "no clock master (physics) found by discovery within 0.5 s (is it running, on an interface this node "
        "browses?): rig time is this node's own clock and will jump when the master appears"]


def test_a_node_with_no_way_to_find_its_master_says_why(caplog: pytest.LogCaptureFixture,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(runtime, "MASTER_SILENT_WARN_S", 0.5)
    run_node(False, caplog, until_s=1.0)
    assert said(caplog, logging.WARNING) == [
        "no clock master (physics) within 0.2 s, and no way to find one: discovery is off and no --peer names a "
        "physics node: starting on this node's own clock for good"]  # once: nothing more to wait for


