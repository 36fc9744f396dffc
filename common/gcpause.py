"""Pausing Python's cyclic garbage collector around work that makes many objects and no cycles."""

from __future__ import annotations

import contextlib
import gc
from collections.abc import Iterator


@contextlib.contextmanager
def cyclic_gc_paused() -> Iterator[None]:
    """No cyclic garbage collection inside (reference counting still frees everything that forms no cycle).

    For reading and planning long scores: they make millions of small objects (MIDI messages, notes, tuples)
    that form no cycles, and each full collection walked them all again (a fifth of a 200,000-note MIDI read,
    a quarter of the limb distribution of a 29,000-note score), for no memory back. The collector's state
    before is restored after (a caller that had it off keeps it off).
    """
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()
