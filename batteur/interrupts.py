"""Ctrl-C acted on at safe points of a long computation, not wherever it lands."""

from __future__ import annotations

import signal
import threading
from typing import Any


class DeferredCtrlC:
    """Within the block a Ctrl-C (SIGINT) is noted instead of raised wherever the program is, and :meth:`check`
    raises ``KeyboardInterrupt`` at the next safe point; leaving the block does if one came after the last check.
    Outside the main thread signals are not Python's to handle: nothing changes.

    Raised anywhere, it could land in the middle of a talk with worker processes (a queue read, a pool's
    bookkeeping: the pool then waited for ever) or inside a numba kernel, which turns it into a ``SystemError``
    with a traceback."""

    def __init__(self) -> None:
        self.noted = False
        self._previous: Any = None

    def __enter__(self) -> DeferredCtrlC:
        if threading.current_thread() is threading.main_thread():
            self._previous = signal.signal(signal.SIGINT, self._note)
        return self

    def _note(self, signum: int, frame: Any) -> None:
        self.noted = True

    def check(self, *_: object) -> None:
        """Raise ``KeyboardInterrupt`` if a Ctrl-C came (arguments ignored: a run's progress callback)."""
        if self.noted:
            self.noted = False  # acted on once
            raise KeyboardInterrupt

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None, tb: Any) -> None:
        if self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)
        elif threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGINT, signal.default_int_handler)
        if kind is None:
            self.check()
