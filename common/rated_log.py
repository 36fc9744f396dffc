"""Warnings of one kind at most once per interval: a flood of bad input cannot flood the log.

Each service core logs what it refuses or drops this way, by kind (a message
type, a drop reason): the first of a kind is logged, the ones within
``interval_s`` after it are counted and said with the next one logged
("(+N more since the last report)"). Times are the caller's clock, in seconds:
rig time for cores (an offline render logs as a live node would), the
monotonic clock elsewhere.
"""

from __future__ import annotations

import logging
from collections import Counter
from collections.abc import Hashable


class RatedWarnings:
    """WARNING lines of ``logger``, each kind at most once per ``interval_s`` seconds.

    Example::

        warnings = RatedWarnings(log, 1.0)
        warnings.warn("bad_layout", now, "pose of %d values refused", len(values))
    """

    def __init__(self, logger: logging.Logger, interval_s: float) -> None:
        self.logger = logger
        self.interval_s = interval_s
        self._last: dict[Hashable, float] = {}
        """Kind -> the time its last line was logged, seconds."""
        self._held: Counter[Hashable] = Counter()
        """Kind -> lines held back since then."""

    def warn(self, kind: Hashable, now: float, message: str, *args: object) -> bool:
        """Log ``message % args`` (formatted only when logged) unless ``kind`` was logged less than
        ``interval_s`` before ``now`` (seconds); True if it was logged. A clock that went back logs at once."""
        last = self._last.get(kind)
        if last is not None and 0.0 <= now - last < self.interval_s:
            self._held[kind] += 1
            return False
        self._last[kind] = now
        held = self._held.pop(kind, 0)
        text = message % args if args else message
        self.logger.warning("%s%s", text, f" (+{held} more since the last report)" if held else "")
        return True
