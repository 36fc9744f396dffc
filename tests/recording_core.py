"""A stand-in core for runtime tests: it keeps every message the node hands it."""

from __future__ import annotations

from common.core import Outgoing
from common.messages import OscMessage


class RecordingCore:
    """A core playing the service ``role`` (the node reads its ``ROLE``) that keeps every message handed to it in
    ``handled``, answers none and never steps (rate 0 keeps the test light)."""

    rate_hz = 0.0

    def __init__(self, role: str = "sound") -> None:
        self.ROLE = role
        self.handled: list[OscMessage] = []

    def handle(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        self.handled.append(message)
        return []

    def step(self, now: float) -> list[Outgoing]:
        return []
