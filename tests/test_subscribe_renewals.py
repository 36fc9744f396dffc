"""``batteur echo`` renews its Subscribe every 5 s: the node logs the first (or a changed) subscription at INFO and
the renewals at DEBUG, and never copies a subscriber's own Subscribe back to it (``batteur echo '/batteur/*'``
printed its own renewals); another subscriber's Subscribe is traffic like any other and is still copied."""

from __future__ import annotations

import asyncio
import logging

import pytest

from common.config import load_settings
from common.messages import OscMessage, Subscribe
from common.runtime import Node
from tests.null_core import NullCore
from tests.waiting import wait_for

pytestmark = pytest.mark.timeout(60)


def test_renewals_are_quiet_and_a_subscriber_gets_no_copy_of_its_own_subscribe(
        caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.DEBUG, logger="batteur.runtime")

    def forwarding() -> list[logging.LogRecord]:
        return [r for r in caplog.records if r.getMessage().startswith("forwarding /batteur/* to ")]

    async def main() -> None:
        from common.transport import UdpEndpoint

        node = Node(NullCore(), load_settings({"role": "sound", "node_id": "sound-1", "discovery": False,
                                                "clock_master": "self"}))
        task = asyncio.ensure_future(node.run())
        await wait_for(lambda: node.endpoint is not None)
        assert node.endpoint is not None
        target = node.endpoint.local_address
        echo = await UdpEndpoint.open()
        got: list[OscMessage] = []
        echo.set_handler(lambda m, s: got.append(m))
        mine = Subscribe(pattern="/batteur/*", duration_s=10.0)
        for sent in (1, 2, 3):  # the first, then two renewals
            echo.send(mine, target)
            await wait_for(lambda sent=sent: len(forwarding()) == sent)
        echo.send(Subscribe(pattern="/batteur/*", duration_s=20.0), target)  # a changed subscription
        await wait_for(lambda: len(forwarding()) == 4)
        assert [r.levelno for r in forwarding()] == [logging.INFO, logging.DEBUG, logging.DEBUG, logging.INFO]
        # another subscriber's Subscribe reaches echo; the node handled echo's own before it (one socket, in order)
        other = await UdpEndpoint.open()
        theirs = Subscribe(pattern="/batteur/{impact,subscribe}", duration_s=10.0)
        other.send(theirs, target)
        await wait_for(lambda: theirs in got)
        assert [m for m in got if isinstance(m, Subscribe)] == [theirs]
        node.request_stop()
        await asyncio.wait_for(task, 3.0)
        echo.close()
        other.close()

    asyncio.run(main())
