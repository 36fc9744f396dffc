"""In-memory message bus with the same interface as the UDP transport.

Every message is encoded to OSC bytes and decoded again on delivery, so the
offline path validates exactly as the wire does. Delivery is synchronous and
ordered, which keeps offline runs deterministic.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

from common.core import Core, Outgoing
from common.messages import OscMessage, decode, encode
from common.messages.registry import REGISTRY, MessageRegistry
from common.stats import TrafficStats

Handler = Callable[[OscMessage, str], None]
"""Receives (message, source) where source names the sender ("role" or "host:port")."""


class MemoryEndpoint:
    """One participant on a :class:`MemoryBus`, addressed by its role."""

    def __init__(self, bus: MemoryBus, role: str) -> None:
        self.bus = bus
        self.role = role
        self.stats = TrafficStats()
        self._handler: Handler | None = None

    def set_handler(self, handler: Handler) -> None:
        self._handler = handler

    def send(self, message: OscMessage, to: str) -> None:
        """Queue ``message`` for every endpoint of role ``to`` (or a watcher of all traffic)."""
        self.stats.messages_out += 1
        self.bus.post(encode(message), to, self.role)

    def receive(self, data: bytes, source: str) -> None:
        decoded = decode(data, self.bus.registry)
        for error in decoded.errors:
            self.stats.record_drop(error.reason, str(error), source)
        for message in decoded.messages:
            self.stats.messages_in += 1
            if self._handler is not None:
                self._handler(message, source)


class MemoryBus:
    """Routes encoded messages between endpoints by role, in posting order."""

    def __init__(self, registry: MessageRegistry = REGISTRY) -> None:
        self.registry = registry
        self.endpoints: dict[str, MemoryEndpoint] = {}
        self.taps: list[Callable[[OscMessage, str, str], None]] = []
        self._queue: deque[tuple[bytes, str, str]] = deque()
        self._delivering = False

    def endpoint(self, role: str) -> MemoryEndpoint:
        if role in self.endpoints:
            raise ValueError(f"role {role!r} already has an endpoint on this bus")
        ep = MemoryEndpoint(self, role)
        self.endpoints[role] = ep
        return ep

    def tap(self, callback: Callable[[OscMessage, str, str], None]) -> None:
        """Watch every delivered message as (message, source role, destination role)."""
        self.taps.append(callback)

    def post(self, data: bytes, to: str, source: str) -> None:
        self._queue.append((data, to, source))
        if not self._delivering:
            self.flush()

    def flush(self) -> None:
        """Deliver queued messages (and whatever they cause) until the queue is empty."""
        self._delivering = True
        try:
            while self._queue:
                data, to, source = self._queue.popleft()
                if self.taps:
                    for message in decode(data, self.registry).messages:
                        for tap in self.taps:
                            tap(message, source, to)
                target = self.endpoints.get(to)
                if target is not None:
                    target.receive(data, source)
        finally:
            self._delivering = False


class OfflineRunner:
    """Runs cores together in one process on a :class:`MemoryBus`, with explicit time.

    Each core is stepped at its own ``rate_hz`` on a shared simulated clock;
    event-driven cores (rate 0) only handle messages. Deterministic.
    """

    def __init__(self, cores: list[Core], registry: MessageRegistry = REGISTRY, start_s: float = 0.0) -> None:
        """``start_s``: rig time the run starts at, seconds (each core's first step is its first one after it)."""
        self.bus = MemoryBus(registry)
        self.cores = cores
        self._endpoints: dict[str, MemoryEndpoint] = {}
        self._schedules: dict[str, _Schedule] = {}
        self.now = start_s
        for core in cores:
            ep = self.bus.endpoint(core.ROLE)
            self._endpoints[core.ROLE] = ep
            ep.set_handler(self._make_handler(core, ep))
            self._schedules[core.ROLE] = _Schedule.starting(core.rate_hz, start_s)

    def _make_handler(self, core: Core, ep: MemoryEndpoint) -> Handler:
        def handle(message: OscMessage, source: str) -> None:
            self._send_all(ep, core.handle(message, self.now, source), reply_to=source)

        return handle

    def _send_all(self, ep: MemoryEndpoint, outgoing: list[Outgoing], reply_to: str = "") -> None:
        for out in outgoing:
            ep.send(out.message, reply_to if out.to == "reply" else out.to)

    def run_until(self, t_end: float, on_progress: Callable[[float], None] | None = None) -> None:
        """Advance every stepped core until rig time ``t_end`` (seconds)."""
        by_role = {c.ROLE: c for c in self.cores}
        schedules = self._schedules
        while True:
            next_step: tuple[float, str] | None = None
            for role, core in by_role.items():
                sched = schedules[role]
                if core.rate_hz != sched.rate_hz:  # changed in a step or a handle: follow it from now
                    sched = schedules[role] = sched.following(core.rate_hz, self.now)
                if sched.rate_hz > 0:
                    candidate = (sched.due(), role)
                    if next_step is None or candidate < next_step:
                        next_step = candidate
            if next_step is None or next_step[0] > t_end:
                break
            due, role = next_step
            self.now = due
            self._send_all(self._endpoints[role], by_role[role].step(due))
            self._schedules[role].steps += 1
            if on_progress is not None:
                on_progress(due)
        self.now = t_end

    def stats(self, role: str) -> TrafficStats:
        return self._endpoints[role].stats


@dataclass
class _Schedule:
    """When a core's next step is due: step ``steps`` at ``origin_s + (steps - origin_steps) / rate_hz`` seconds.

    Times come from step counts, not accumulated periods, so long runs do not drift; a rate change starts a
    new origin at the time it was seen, the next step one new period later: times never go back.
    """

    rate_hz: float
    steps: int
    origin_s: float = 0.0
    origin_steps: int = 0

    @classmethod
    def starting(cls, rate_hz: float, start_s: float) -> _Schedule:
        """The first step at or after ``start_s`` seconds (none for an event-driven core, rate 0)."""
        rate = _usable_rate(rate_hz)
        return cls(rate, math.ceil(start_s * rate - 1e-9) if rate > 0 else 0)

    def due(self) -> float:
        return self.origin_s + (self.steps - self.origin_steps) / self.rate_hz

    def following(self, rate_hz: float, now_s: float) -> _Schedule:
        """This schedule, or a new one from ``now_s`` seconds when the core's rate is no longer ``rate_hz``."""
        rate = _usable_rate(rate_hz)
        if rate == self.rate_hz:
            return self
        return _Schedule(rate, 1, origin_s=now_s) if rate > 0 else _Schedule(0.0, 0)


def _usable_rate(rate_hz: float) -> float:
    """A core's rate as the runner steps it (Hz): 0 (event-driven) for 0, negative or non-finite rates."""
    return float(rate_hz) if math.isfinite(rate_hz) and rate_hz > 0 else 0.0
