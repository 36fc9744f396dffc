"""A core that does nothing: for tests of what the runtime's Node does around any core."""

from __future__ import annotations

from typing import ClassVar

from common.core import Outgoing
from common.messages import OscMessage


class NullCore:
    """Event-driven (``rate_hz`` 0), answers nothing, steps to nothing; its role is ``sound``."""

    ROLE: ClassVar[str] = "sound"
    rate_hz = 0.0

    def handle(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        return []

    def step(self, now: float) -> list[Outgoing]:
        return []
