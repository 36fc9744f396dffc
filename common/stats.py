"""Traffic counters shared by the UDP transport and the in-memory bus.

Drops are counted per :class:`~common.messages.DropReason` and logged at most
once per reason per interval, so a flood of bad packets cannot flood the log.
"""

from __future__ import annotations

import logging
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field

from common.messages import DropReason
from common.rated_log import RatedWarnings

log = logging.getLogger("batteur.traffic")


@dataclass
class TrafficStats:
    """Messages in and out, and drops by reason, since start."""

    log_interval_s: float = 5.0
    clock: Callable[[], float] = time.monotonic
    messages_in: int = 0
    messages_out: int = 0
    dropped: Counter[DropReason] = field(default_factory=Counter)
    _warnings: RatedWarnings = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self._warnings = RatedWarnings(log, self.log_interval_s)

    def record_drop(self, reason: DropReason, detail: str, source: str = "") -> None:
        """Count one dropped message and log it unless this reason was logged within ``log_interval_s``."""
        self.dropped[reason] += 1
        self._warnings.warn(reason, self.clock(), "dropped %s from %s: %s", reason.value, source or "?", detail)

    @property
    def dropped_total(self) -> int:
        return sum(self.dropped.values())

    def drops_by_reason(self) -> dict[str, int]:
        return {reason.value: self.dropped[reason] for reason in DropReason}
