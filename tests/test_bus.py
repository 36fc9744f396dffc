"""The in-memory bus and the offline runner: same validation as the wire, deterministic stepping."""

from __future__ import annotations

from typing import ClassVar

from common.bus import MemoryBus, OfflineRunner
from common.core import Outgoing
from common.messages import DropReason, Hello, OscMessage, encode_raw


class Ticker:
    """Sends a Hello to 'listener' on every step."""

    ROLE: ClassVar[str] = "ticker"

    def __init__(self, rate_hz: float) -> None:
        self.rate_hz = rate_hz
        self.steps: list[float] = []

    def handle(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        return []

    def step(self, now: float) -> list[Outgoing]:
        self.steps.append(now)
        return [Outgoing(Hello(role="ticker", node_id="t", protocol=1, osc_port=len(self.steps)), "listener")]


class Listener:
    """Records what it receives and answers each message to its sender."""

    ROLE: ClassVar[str] = "listener"
    rate_hz = 0.0

    def __init__(self) -> None:
        self.received: list[tuple[float, OscMessage, str]] = []

    def handle(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        self.received.append((now, message, source))
        return [Outgoing(Hello(role="listener", node_id="l", protocol=1, osc_port=0), "reply")]

    def step(self, now: float) -> list[Outgoing]:
        return []


def test_runner_steps_each_core_at_its_rate_and_routes_by_role() -> None:
    fast, slow, listener = Ticker(1000.0), Ticker(60.0), Listener()
    slow.ROLE = "slow"  # type: ignore[misc]
    runner = OfflineRunner([fast, slow, listener])
    runner.run_until(1.0)
    assert len(fast.steps) == 1001  # t = 0, 1 ms, ..., 1 s
    assert len(slow.steps) == 61
    assert fast.steps[-1] == 1.0  # step counts, no accumulated drift
    sources = [source for _, _, source in listener.received]
    assert sources.count("ticker") == 1001 and sources.count("slow") == 61
    assert runner.stats("ticker").messages_in == 1001  # the replies went back to each sender
    assert runner.stats("slow").messages_in == 61


def test_runner_is_deterministic() -> None:
    def run() -> list[tuple[float, int]]:
        ticker, listener = Ticker(250.0), Listener()
        OfflineRunner([ticker, listener]).run_until(0.5)
        return [(t, m.osc_port) for t, m, _ in listener.received if isinstance(m, Hello)]

    assert run() == run()


def test_bus_drops_bad_messages_with_their_reason() -> None:
    bus = MemoryBus()
    a = bus.endpoint("a")
    got: list[OscMessage] = []
    a.set_handler(lambda message, source: got.append(message))
    bus.post(encode_raw("/batteur/hello", ["x"]), "a", "test")
    bus.post(encode_raw("/unknown", []), "a", "test")
    bus.post(encode_raw("/batteur/hello", ["sound", "n1", 1, 9000]), "a", "test")
    assert len(got) == 1
    assert a.stats.dropped[DropReason.WRONG_ARITY] == 1
    assert a.stats.dropped[DropReason.UNKNOWN_ADDRESS] == 1
