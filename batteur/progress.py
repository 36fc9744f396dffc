"""A small progress bar for long offline work, on stderr (quiet when not a terminal unless forced)."""

from __future__ import annotations

import sys
import time
from typing import TextIO


class Progress:
    """Prints ``label [#####.....] 42% 3.1 s / 7.4 s`` at most every ``interval_s``."""

    def __init__(self, label: str, total: float, unit: str = "s", stream: TextIO | None = None,
                 interval_s: float = 0.2, enabled: bool | None = None, decimals: int = 1) -> None:
        """``decimals``: digits shown after the point of the amounts done and in all (0 for counts)."""
        self.label = label
        self.total = max(total, 1e-9)
        self.unit = unit
        self.stream = stream if stream is not None else sys.stderr
        self.interval_s = interval_s
        self.enabled = self.stream.isatty() if enabled is None else enabled
        self.decimals = decimals
        self._drawn = False
        self._last = 0.0
        self._start = time.monotonic()

    def update(self, done: float) -> None:
        now = time.monotonic()
        if not self.enabled or (now - self._last < self.interval_s and done < self.total):
            return
        self._last = now
        self._drawn = True
        frac = min(1.0, max(0.0, done / self.total))
        bar = "#" * int(frac * 30)
        d = self.decimals
        self.stream.write(f"\r{self.label} [{bar:<30}] {frac:4.0%} {done:.{d}f} {self.unit} / {self.total:.{d}f} "
                          f"{self.unit} ({now - self._start:.1f} s)")
        self.stream.flush()

    def close(self, finished: bool = True) -> None:
        """Draw the bar full and end its line; ``finished=False`` (the work was given up, e.g. Ctrl-C): end the
        line where the bar stands, if it was drawn at all."""
        if self.enabled and (finished or self._drawn):
            if finished:
                self.update(self.total)
            self.stream.write("\n")
            self.stream.flush()
