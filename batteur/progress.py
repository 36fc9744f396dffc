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
        """Show ``done`` (in ``unit``), unless the bar was drawn less than ``interval_s`` ago: however far the work
        runs past the total (a total too short), only :meth:`close` draws regardless."""
        now = time.monotonic()
        if self.enabled and now - self._last >= self.interval_s:
            self._draw(done, now)

    def _draw(self, done: float, now: float) -> None:
        """Draw the bar with ``done`` clamped to 0 .. total: past the total it shows 100 % and the total, so the
        amount never goes past the total and then back at :meth:`close`."""
        self._last = now
        self._drawn = True
        shown = min(self.total, max(0.0, done))
        frac = shown / self.total
        bar = "#" * int(frac * 30)
        d = self.decimals
        self.stream.write(f"\r{self.label} [{bar:<30}] {frac:4.0%} {shown:.{d}f} {self.unit} / {self.total:.{d}f} "
                          f"{self.unit} ({now - self._start:.1f} s)")
        self.stream.flush()

    def close(self, finished: bool = True) -> None:
        """Draw the bar full and end its line; ``finished=False`` (the work was given up, e.g. Ctrl-C): end the
        line where the bar stands, if it was drawn at all."""
        if self.enabled and (finished or self._drawn):
            if finished:
                self._draw(self.total, time.monotonic())
            self.stream.write("\n")
            self.stream.flush()
