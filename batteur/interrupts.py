"""Ctrl-C and SIGTERM acted on at safe points of a long computation, not wherever they land."""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator
from typing import Any


class Terminated(KeyboardInterrupt):
    """SIGTERM (``timeout``, systemd, a render farm's scheduler, ``kill``): raised as a Ctrl-C is, so that the code
    that cleans up after a Ctrl-C (a render's staging) does after it too (until 8 Dec SIGTERM's default action ended
    the process at once, leaving a render's ``.render-*`` folder behind, and said nothing)."""


def _raise_terminated(signum: int, frame: Any) -> None:
    raise Terminated


@contextlib.contextmanager
def sigterm_raises() -> Iterator[None]:
    """Within the block SIGTERM raises :class:`Terminated` wherever the program is, as Python's own handler raises
    ``KeyboardInterrupt`` for SIGINT (:class:`DeferredCtrlC` defers both). Outside the main thread, or when SIGTERM
    is ignored (``nohup``-like launchers that mean it so), nothing changes."""
    if threading.current_thread() is not threading.main_thread() or signal.getsignal(signal.SIGTERM) == signal.SIG_IGN:
        yield
        return
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


class DeferredCtrlC:
    """Within the block a Ctrl-C (SIGINT) or SIGTERM is noted instead of raised wherever the program is, and
    :meth:`check` raises ``KeyboardInterrupt`` (:class:`Terminated` for SIGTERM) at the next safe point; leaving the
    block does if one came after the last check. Outside the main thread signals are not Python's to handle: nothing
    changes.

    Raised anywhere, it could land in the middle of a talk with worker processes (a queue read, a pool's
    bookkeeping: the pool then waited for ever) or inside a numba kernel, which turns it into a ``SystemError``
    with a traceback."""

    def __init__(self) -> None:
        self.noted = False
        self.terminated = False
        """The signal noted was SIGTERM (it wins over a Ctrl-C noted with it)."""
        self._previous: Any = None
        self._previous_term: Any = None

    def __enter__(self) -> DeferredCtrlC:
        if threading.current_thread() is threading.main_thread():
            self._previous = signal.signal(signal.SIGINT, self._note)
            if signal.getsignal(signal.SIGTERM) != signal.SIG_IGN:  # ignored: meant so by whoever started us
                self._previous_term = signal.signal(signal.SIGTERM, self._note)
        return self

    def _note(self, signum: int, frame: Any) -> None:
        self.noted = True
        self.terminated = self.terminated or signum == signal.SIGTERM

    def check(self, *_: object) -> None:
        """Raise ``KeyboardInterrupt`` if a Ctrl-C came, :class:`Terminated` if SIGTERM did (arguments ignored: a
        run's progress callback)."""
        if self.noted:
            terminated = self.terminated
            self.noted = self.terminated = False  # acted on once
            raise Terminated if terminated else KeyboardInterrupt

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None, tb: Any) -> None:
        if self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)
        elif threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGINT, signal.default_int_handler)
        if self._previous_term is not None:
            signal.signal(signal.SIGTERM, self._previous_term)
        if kind is None:
            self.check()
