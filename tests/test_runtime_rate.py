"""A node follows its core's ``rate_hz`` when the core changes it while running (interaction's Redundancy and
configuration messages do): the loop's period from the next iteration, event-driven at 0, and Health's
target rate; a value that is no rate is refused with a log line and the old rate kept."""

from __future__ import annotations

import asyncio
import logging
from typing import ClassVar

import pytest

from common.config import load_settings
from common.core import Outgoing
from common.messages import Impact, OscMessage
from common.runtime import Node, RateLoop
from tests.test_runtime import FakeTime
from tests.waiting import wait_for

pytestmark = pytest.mark.timeout(60)


# --------------------------------------------------------------------------- the loop


def test_a_rate_change_applies_from_the_deadline_after_the_current_tick() -> None:
    fake = FakeTime()
    starts: list[float] = []
    loop: RateLoop

    def tick() -> None:
        starts.append(fake.t)
        if len(starts) == 5:  # tick 4 (at 40 ms): the core now wants 1 kHz
            loop.set_rate(1000.0)
        fake.t += 0.0001

    loop = RateLoop(100.0, tick, clock=fake, sleep_until=fake.sleep_until)
    asyncio.run(loop.run(max_ticks=10))
    assert starts[:5] == pytest.approx([0.0, 0.01, 0.02, 0.03, 0.04])
    # anchored on the deadline of the tick that changed it: no drift, no burst of catch-up ticks
    assert starts[5:] == pytest.approx([0.041, 0.042, 0.043, 0.044, 0.045])
    assert loop.rate_hz == 1000.0 and loop.period == pytest.approx(0.001)
    assert loop.overruns == 0 and loop.skipped == 0


def test_a_rate_change_between_ticks_applies_after_the_deadline_already_waited_for() -> None:
    fake = FakeTime()
    starts: list[float] = []
    loop: RateLoop

    async def sleep_until(deadline: float) -> None:
        if len(starts) == 3:  # a message handled while the loop waits for its 4th deadline
            loop.set_rate(50.0)
        await fake.sleep_until(deadline)

    loop = RateLoop(100.0, lambda: starts.append(fake.t), clock=fake, sleep_until=sleep_until)
    asyncio.run(loop.run(max_ticks=6))
    assert starts == pytest.approx([0.0, 0.01, 0.02, 0.03, 0.05, 0.07])


@pytest.mark.parametrize("rate", [0.0, -1.0, float("nan"), float("inf")])
def test_the_loop_refuses_a_rate_that_is_no_positive_finite_number(rate: float) -> None:
    loop = RateLoop(100.0, lambda: None)
    with pytest.raises(ValueError):
        loop.set_rate(rate)
    assert loop.rate_hz == 100.0


def test_a_stopped_loop_ends_after_its_tick_and_runs_again_keeping_its_counts() -> None:
    fake = FakeTime()
    loop: RateLoop

    def tick() -> None:
        if loop.ticks == 2:
            loop.stop()

    loop = RateLoop(100.0, tick, clock=fake, sleep_until=fake.sleep_until)
    asyncio.run(loop.run())  # returns (it ran for ever before)
    assert loop.ticks == 3 and not loop.running
    loop.set_rate(50.0)  # the core wants steps again
    asyncio.run(loop.run(max_ticks=5))
    assert loop.ticks == 5


# --------------------------------------------------------------------------- the node


class RateCore:
    """Steps at ``rate_hz``; each Impact makes it take the next rate of ``rates`` (as interaction's
    configuration messages change its rate)."""

    ROLE: ClassVar[str] = "echo"

    def __init__(self, rate_hz: float, rates: list[float]) -> None:
        self.rate_hz = rate_hz
        self.rates = rates
        self.steps = 0
        self.handled = 0

    def handle(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        if isinstance(message, Impact):
            self.rate_hz = self.rates.pop(0)
            self.handled += 1
        return []

    def step(self, now: float) -> list[Outgoing]:
        self.steps += 1
        return []


def impact() -> Impact:
    return Impact(seq=1, time=1.0, instrument="snare", zone="centre", r=0.25, theta=0.0, velocity=2.0,
                  impulse=0.0625, peak_force=10.0, duration=0.00390625, part="stick")


def test_the_node_follows_its_cores_rate_and_refuses_values_that_are_no_rate(
        caplog: pytest.LogCaptureFixture) -> None:
    core = RateCore(0.0, [200.0, 50.0, float("nan"), -5.0, float("inf"), 0.0, 100.0])

    async def main() -> None:
        node = Node(core, load_settings({"role": "echo", "discovery": False, "clock_master": "self"}))
        task = asyncio.ensure_future(node.run())
        await wait_for(lambda: node.endpoint is not None)
        assert node.endpoint is not None and node.loop is None  # event-driven at first

        async def change() -> None:
            handled = core.handled
            assert node.endpoint is not None
            node.endpoint.send(impact(), node.endpoint.local_address)
            await wait_for(lambda: core.handled == handled + 1)

        await change()  # 0 -> 200 Hz: the node starts stepping
        await wait_for(lambda: core.steps >= 5)
        loop = node.loop
        assert loop is not None and loop.rate_hz == 200.0 and node.health().target_rate_hz == 200.0
        await change()  # 200 -> 50 Hz
        await wait_for(lambda: loop.rate_hz == 50.0)
        assert loop.period == pytest.approx(0.02) and node.health().target_rate_hz == 50.0
        for bad in ("nan", "-5", "inf"):
            caplog.clear()
            await change()
            assert node.rate_hz == 50.0 and node.health().target_rate_hz == 50.0 and loop.rate_hz == 50.0
            said = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
            assert any(bad in line and "keeping 50 Hz" in line for line in said), said
        await change()  # 50 -> 0: event-driven, no more steps
        await wait_for(lambda: not loop.running)
        assert node.health().target_rate_hz == 0.0
        steps = core.steps
        await asyncio.sleep(0.1)
        assert core.steps == steps
        ticks = loop.ticks
        await change()  # 0 -> 100 Hz: stepping again, with the same loop and its totals (Health's overruns)
        await wait_for(lambda: core.steps >= steps + 5)
        assert node.loop is loop and loop.rate_hz == 100.0 and loop.ticks >= ticks + 5
        assert node.health().target_rate_hz == 100.0
        node.request_stop()
        await asyncio.wait_for(task, 3.0)

    caplog.set_level(logging.INFO, logger="batteur.runtime")
    asyncio.run(main())


def test_a_rate_given_on_the_command_line_stays_when_the_core_changes_its_own() -> None:
    core = RateCore(300.0, [40.0])

    async def main() -> None:
        settings = load_settings({"role": "echo", "discovery": False, "clock_master": "self", "rate_hz": 100})
        node = Node(core, settings)
        task = asyncio.ensure_future(node.run())
        await wait_for(lambda: node.endpoint is not None and core.steps >= 3)
        assert node.endpoint is not None and node.loop is not None
        node.endpoint.send(impact(), node.endpoint.local_address)
        await wait_for(lambda: core.handled == 1)
        steps = core.steps
        await wait_for(lambda: core.steps >= steps + 2)  # the loop has checked the core since
        assert node.loop.rate_hz == 100.0 and node.health().target_rate_hz == 100.0  # --rate-hz is an override
        node.request_stop()
        await asyncio.wait_for(task, 3.0)

    asyncio.run(main())


@pytest.mark.parametrize("rate", [float("inf"), float("nan"), -1.0])
def test_a_node_refuses_a_core_that_starts_at_no_rate(rate: float) -> None:
    # was: inf stepped in a busy loop (period 0), NaN never stepped and sent Health no receiver accepts
    with pytest.raises(ValueError, match="not a rate"):
        Node(RateCore(rate, []), load_settings({"role": "echo", "discovery": False, "clock_master": "self"}))
