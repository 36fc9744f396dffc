"""Progress of long offline work, on stderr: a bar redrawn in place on a terminal with an estimate of the time left;
elsewhere (piped to a log, CI) a plain line now and then, so a long run shows it is alive; nothing when quiet."""

from __future__ import annotations

import sys
import time
from typing import TextIO

ESTIMATE_AFTER_FRACTION = 0.03
"""The time left is estimated once this much of the work is done (before, the rate is mostly start-up) ..."""
ESTIMATE_AFTER_S = 2.0
"""... and this many seconds have passed since the work started."""
LOG_EVERY_S = 30.0
"""Not on a terminal: a line at least this often (seconds), the first this long after the start ..."""
LOG_EVERY_FRACTION = 0.1
"""... and one whenever this much more of the work is done than at the line before (whichever comes first): work
done within :data:`LOG_EVERY_S` prints nothing, a long one a line every 30 s or every 10 %. Until 8 Dec it was
whichever was rarer: a render slower than 10 % in 30 s (a 10-minute piece) went minutes without a line."""


def duration_words(seconds: float) -> str:
    """``seconds`` rounded as said of a time left: ``1 s`` (never 0), ``42 s``, ``7 min``, ``2 h 05 min``."""
    if seconds < 99.5:
        return f"{max(1, round(seconds))} s"
    minutes = round(seconds / 60.0)
    if minutes < 60:
        return f"{minutes} min"
    return f"{minutes // 60} h {minutes % 60:02d} min"


class Progress:
    """``label [#####.....] 42% 3.1 s / 7.4 s (12.0 s, about 17 s left)`` redrawn at most every ``interval_s`` on a
    terminal (or ``enabled=True``); elsewhere a line ``label: 42% 3.1 s / 7.4 s (12 s, about 17 s left)`` every
    ``log_every_s`` or ``log_every_fraction`` of the work, whichever comes first, none in the first ``log_every_s``
    (and a last one at :meth:`close` if any was printed); ``enabled=False``: nothing."""

    def __init__(self, label: str, total: float, unit: str = "s", stream: TextIO | None = None,
                 interval_s: float = 0.2, enabled: bool | None = None, decimals: int = 1,
                 log_every_s: float = LOG_EVERY_S, log_every_fraction: float = LOG_EVERY_FRACTION) -> None:
        """``decimals``: digits shown after the point of the amounts done and in all (0 for counts)."""
        self.label = label
        self.total = max(total, 1e-9)
        self.unit = unit
        self.stream: TextIO | None = stream if stream is not None else sys.stderr  # None: stderr closed (2>&-)
        self.interval_s = interval_s
        if self.stream is None:
            enabled = False
        terminal = self.stream.isatty() if enabled is None and self.stream is not None else bool(enabled)
        self.enabled = terminal
        """The bar is drawn (a terminal, or forced)."""
        self.logging = enabled is None and not terminal
        """Not a terminal and not quiet: plain lines now and then instead of the bar."""
        self.decimals = decimals
        self.log_every_s = log_every_s
        self.log_every_fraction = log_every_fraction
        self._drawn = False
        self._width = 0  # of the last bar drawn: a shorter one is padded over it
        self._start = time.monotonic()
        self._last = 0.0
        self._logged = self._start  # when the last plain line was printed (the start before any)
        self._logged_frac = 0.0
        self._logged_any = False

    def update(self, done: float) -> None:
        """Show ``done`` (in ``unit``), unless the bar was drawn less than ``interval_s`` ago (a plain line: printed
        less than ``log_every_s`` ago and less than ``log_every_fraction`` further, or the work started less than
        ``log_every_s`` ago): however far the work runs past the total (a total too short), only :meth:`close` draws
        regardless."""
        if not (self.enabled or self.logging):
            return
        now = time.monotonic()
        if self.enabled:
            if now - self._last >= self.interval_s:
                self._draw(done, now)
        elif now - self._start >= self.log_every_s and (
                now - self._logged >= self.log_every_s
                or self._fraction(done) - self._logged_frac >= self.log_every_fraction - 1e-9):  # 0.3 - 0.2 < 0.1
            self._log(done, now)

    def _fraction(self, done: float) -> float:
        return min(self.total, max(0.0, done)) / self.total

    def _amounts(self, done: float) -> str:
        """``42% 3.1 s / 7.4 s``, ``done`` clamped to 0 .. total: past the total it shows 100 % and the total, so the
        amount never goes past the total and then back at :meth:`close`. The percentage is rounded down: 100 % only
        when it is done (99.6 % read "100%" and off a terminal the last line said it again until 8 Dec)."""
        shown = min(self.total, max(0.0, done))
        d = self.decimals
        percent = int(shown / self.total * 100 + 1e-9)
        return f"{percent:3d}% {shown:.{d}f} {self.unit} / {self.total:.{d}f} {self.unit}"

    def _left(self, done: float, elapsed_s: float) -> str:
        """``, about 17 s left`` once an estimate means something (:data:`ESTIMATE_AFTER_FRACTION`,
        :data:`ESTIMATE_AFTER_S`; the rate so far held), else "" (and at 100 %)."""
        frac = self._fraction(done)
        if not ESTIMATE_AFTER_FRACTION <= frac < 1.0 or elapsed_s < ESTIMATE_AFTER_S:
            return ""
        return f", about {duration_words(elapsed_s * (1.0 - frac) / frac)} left"

    def _draw(self, done: float, now: float) -> None:
        """Draw the bar (``done`` clamped as :meth:`_amounts`), padded over a longer one drawn before (the estimate
        is gone at 100 %)."""
        self._last = now
        self._drawn = True
        elapsed = now - self._start
        bar = "#" * int(self._fraction(done) * 30)
        text = f"{self.label} [{bar:<30}] {self._amounts(done)} ({elapsed:.1f} s{self._left(done, elapsed)})"
        self._write(f"\r{text:<{self._width}}")
        self._width = len(text)

    def _log(self, done: float, now: float) -> None:
        """Print a plain line (not on a terminal)."""
        self._logged = now
        self._logged_frac = self._fraction(done)
        self._logged_any = True
        elapsed = now - self._start
        self._write(f"{self.label}: {self._amounts(done).lstrip()} ({elapsed:.0f} s{self._left(done, elapsed)})\n")

    def _write(self, text: str) -> None:
        """Write and flush ``text``; a stream that can no longer be written (a closed pipe: ``... 2>&1 | head``, a
        log reader that died) silences the progress for good rather than stopping the work it shows."""
        if self.stream is None:
            return
        try:
            self.stream.write(text)
            self.stream.flush()
        except (OSError, ValueError):
            self.enabled = self.logging = False
            self.stream = None

    def close(self, finished: bool = True) -> None:
        """Draw the bar full and end its line; ``finished=False`` (the work was given up, e.g. Ctrl-C): end the
        line where the bar stands, if it was drawn at all. Not on a terminal: a last line at 100 % when the work
        finished and lines were printed (a short run prints none; not a second one at 100 %), nothing when it was
        given up (its error says)."""
        if self.enabled and (finished or self._drawn):
            if finished:
                self._draw(self.total, time.monotonic())
            self._write("\n")
        elif self.logging and finished and self._logged_any and self._logged_frac < 1.0:  # not twice at 100 %
            self._log(self.total, time.monotonic())
