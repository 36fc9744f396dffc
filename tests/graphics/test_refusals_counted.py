"""Refusals of the graphics service are counted in its Health, as physics', sound's and interaction's are (an OSC
walkthrough found ``/batteur/graphics/mode preview`` with no preview answered but not counted, and poses of the
wrong length or of an unknown layout dropped with no log line and no count but ``messages_in``)."""

from __future__ import annotations

import asyncio
import logging

import pytest

from common.config import NodeSettings
from common.messages import Pose, Skeleton
from common.messages.graphics import GraphicsMode
from common.runtime import Node
from common.transport import UdpEndpoint
from services.graphics.core import REFUSAL_LOG_INTERVAL_S, GraphicsCore, GraphicsSettings
from tests.waiting import wait_for

pytestmark = pytest.mark.timeout(60)

NAMES = ("pelvis", "right_stick_tip")
REST = (0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0) * len(NAMES)


def _core() -> GraphicsCore:
    core = GraphicsCore(GraphicsSettings(latency=0.0, clock="rig"))
    core.handle(Skeleton(layout=1, names=NAMES), 0.0, "127.0.0.1:9")
    return core


def test_the_refused_preview_mode_and_bad_poses_are_refusals_of_the_core(caplog: pytest.LogCaptureFixture) -> None:
    core = _core()
    caplog.set_level(logging.WARNING, "batteur.graphics")
    core.handle(Pose(time=0.0, layout=1, values=REST), 0.0, "127.0.0.1:9")  # a good one: taken
    assert core.rejected_total == 0 and not caplog.records
    core.handle(GraphicsMode(mode="preview"), 0.1, "127.0.0.1:9")
    core.handle(Pose(time=0.1, layout=1, values=(0.0,) * 5), 0.2, "127.0.0.1:9")  # not 7 per link
    core.handle(Pose(time=0.2, layout=99, values=REST), 0.3, "127.0.0.1:9")  # an unknown layout
    core.handle(Pose(time=0.3, layout=1, values=REST * 2), 0.4, "127.0.0.1:9")  # 4 links, the skeleton has 2
    assert core.rejected_total == 4
    text = [r.getMessage() for r in caplog.records]
    assert "no preview is loaded" in text[0]
    assert "5 values, not 7 per link" in text[1]
    assert len(text) == 2  # the other pose refusals within the second are counted, not logged
    core.handle(Pose(time=0.3, layout=99, values=REST), 0.2 + REFUSAL_LOG_INTERVAL_S, "127.0.0.1:9")
    assert "layout 99, not the skeleton's 1" in caplog.records[-1].getMessage()
    assert "(+2 more since the last report)" in caplog.records[-1].getMessage()
    assert core.rejected_total == 5


def test_a_wrong_length_is_refused_even_before_any_skeleton_a_valid_pose_then_only_waits() -> None:
    core = GraphicsCore(GraphicsSettings(latency=0.0, clock="rig"))
    core.handle(Pose(time=0.0, layout=1, values=(0.0,) * 5), 0.0, "127.0.0.1:9")
    assert core.rejected_total == 1
    core.handle(Pose(time=0.0, layout=1, values=REST), 0.0, "127.0.0.1:9")  # physics' layout not here yet
    assert core.rejected_total == 1 and core.counters["no_skeleton"] == 1


def test_the_node_health_counts_the_graphics_refusals_as_dropped() -> None:
    async def scenario() -> None:
        core = _core()
        node = Node(core, NodeSettings(role="graphics", discovery=False, oscquery=False, clock_master="self"))
        await node.start()
        client = await UdpEndpoint.open("127.0.0.1")
        try:
            assert node.endpoint is not None
            to = node.endpoint.local_address
            before = node.health()
            client.send(GraphicsMode(mode="preview"), to)
            client.send(Pose(time=0.0, layout=1, values=(0.0,) * 5), to)
            client.send(Pose(time=0.0, layout=99, values=REST), to)
            await wait_for(lambda: core.rejected_total == 3, 10.0)
            after = node.health()
            assert after.dropped - before.dropped == 3
            assert after.dropped_other - before.dropped_other == 3
        finally:
            client.close()
            await node.stop()

    asyncio.run(scenario())
