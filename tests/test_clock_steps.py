"""A follower's rig time that steps (its clock master restarted: rig time starts again from the new master's
launch) is said once in the log and handed to the core's ``clock_stepped``, instead of each core guessing
from time going backward; the estimator's millisecond tracking is no step."""

from __future__ import annotations

import asyncio
import logging
import time
from typing import ClassVar

import pytest

from common.clock import STEP_S, RigClock
from common.config import load_settings
from common.core import Outgoing
from common.messages import OscMessage
from common.runtime import Node
from tests.waiting import wait_for

pytestmark = pytest.mark.timeout(60)


def test_set_offset_reports_steps_not_tracking(caplog: pytest.LogCaptureFixture) -> None:
    clock = RigClock(0.0, wall=lambda: 100.0, monotonic=lambda: 5.0)
    with caplog.at_level(logging.INFO, logger="batteur.clock"):
        assert clock.set_offset(2.0) == pytest.approx(2.0)  # the first sync: counted, said by the node
        assert not caplog.records
        assert clock.set_offset(2.0 + STEP_S / 2) == 0.0  # tracking: no step
        assert clock.set_offset(-33.0) == pytest.approx(-35.0 - STEP_S / 2)  # the master restarted
    assert clock.generation == 2 and clock.last_step_s == pytest.approx(-35.05)
    assert clock.offset == -33.0 and clock.synced
    warned = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert warned == ["rig clock stepped back 35.0 s: the clock master (the clock master) restarted? "
                      "(rig time now 67.0 s)"]


class StepCore:
    """Event-driven; records the steps of rig time its node hands it."""

    ROLE: ClassVar[str] = "sound"
    rate_hz = 0.0

    def __init__(self) -> None:
        self.stepped: list[tuple[float, float]] = []

    def handle(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        return []

    def step(self, now: float) -> list[Outgoing]:
        return []

    def clock_stepped(self, step_s: float, now: float) -> list[Outgoing]:
        self.stepped.append((step_s, now))
        return []


async def synced_follower() -> tuple[Node, Node, StepCore, float]:
    """A physics node (the clock master) on loopback and a sound node following it by a static --peer, started and
    synced (8 samples): (master, follower, the follower's core, the rig epoch)."""
    epoch = time.time() - 1000.0
    master = Node(StepCore(), load_settings({"role": "physics", "discovery": False, "epoch": epoch}))
    await master.start()
    assert master.endpoint is not None
    core = StepCore()
    remote = Node(core, load_settings({"role": "sound", "discovery": False, "epoch": epoch,
                                       "peers": [f"physics=127.0.0.1:{master.endpoint.port}"]}), ping_interval_s=0.05)
    await remote.start()
    await wait_for(lambda: remote.core_started and len(remote.estimator.samples) >= 8)
    return master, remote, core, epoch


async def restart_master(master: Node, epoch: float) -> Node:
    """Stop ``master`` and start another physics node on its port whose rig time starts 35 s earlier."""
    assert master.endpoint is not None
    port = master.endpoint.port
    await master.stop()
    restarted = Node(StepCore(), load_settings({"role": "physics", "discovery": False, "epoch": epoch + 35.0,
                                                "port": port}))
    await restarted.start()
    return restarted


def test_a_restarted_master_steps_the_followers_core_once(caplog: pytest.LogCaptureFixture) -> None:
    """Physics restarted on the same address (a static --peer, compose): its rig time starts 35 s earlier."""

    async def main() -> None:
        master, remote, core, epoch = await synced_follower()
        assert core.stepped == []  # syncing before the core started is no step of its time
        restarted = await restart_master(master, epoch)
        await wait_for(lambda: bool(core.stepped), timeout=10.0)
        await asyncio.sleep(0.3)  # more pongs of the restarted master: no further step
        assert len(core.stepped) == 1
        step, now = core.stepped[0]
        assert step == pytest.approx(-35.0, abs=0.05)
        assert now == pytest.approx(remote.clock.now(), abs=1.0)
        await remote.stop()
        await restarted.stop()

    with caplog.at_level(logging.INFO):
        asyncio.run(main())
    steps = [r.getMessage() for r in caplog.records if "rig clock stepped" in r.getMessage()]
    assert len(steps) == 1 and steps[0].startswith("rig clock stepped back 35.0 s: the clock master")
