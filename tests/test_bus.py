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


class Retuner(Ticker):
    """A ticker whose rate changes at given times, as interaction's does when its redundancy is set."""

    def __init__(self, rate_hz: float, changes: dict[float, float]) -> None:
        super().__init__(rate_hz)
        self.changes = changes

    def step(self, now: float) -> list[Outgoing]:
        out = super().step(now)
        for at, rate in self.changes.items():
            if abs(now - at) < 1e-9:
                self.rate_hz = rate
        return out


def test_runner_follows_a_core_that_changes_its_rate() -> None:
    # 100 Hz, then 50 Hz from its step at 0.1 s, event-driven (0 Hz) from 0.2 s, then back to stepping at 200 Hz
    # (a message handled at 0.3 s), and a bad rate (NaN) from 0.4 s: it stops stepping, nothing raises
    retuner = Retuner(100.0, {0.1: 50.0, 0.2: 0.0, 0.4: float("nan")})
    waker = Ticker(10.0)
    waker.ROLE = "waker"  # type: ignore[misc]

    class Waking(Listener):
        def handle(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
            if source == "waker" and abs(now - 0.3) < 1e-9:
                retuner.rate_hz = 200.0
            return []

    waking = Waking()
    retuner.ROLE = "ticker"  # type: ignore[misc]
    runner = OfflineRunner([retuner, waker, waking])
    runner.run_until(0.5)
    steps = retuner.steps
    assert steps == sorted(steps) and len(set(steps)) == len(steps)  # time never goes back nor repeats
    assert steps[:11] == [k / 100 for k in range(11)]  # bit-exact step counts before any change
    assert [round(t, 9) for t in steps[11:]] == [0.12, 0.14, 0.16, 0.18, 0.2] + [
        round(0.3 + k / 200, 9) for k in range(1, 21)]
    assert len(waker.steps) == 6 and runner.now == 0.5
