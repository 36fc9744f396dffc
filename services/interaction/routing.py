"""Redundant sending: each message goes out now and again a few times, a little apart.

UDP loses packets; a lost impact is a lost note. Interaction sends every
impact, impact end and damping message ``copies`` times, ``spacing`` seconds
apart, all with the same sequence number; receivers keep the first copy
(common/dedupe.py). With independent losses at rate p, a message is lost only
if every copy is: p ** copies (5 % loss, 5 copies: 3e-7, so 0.003 impacts expected lost in 10,000). Spacing the copies
spreads them over short loss bursts.

Also builds the messages registered at run time: an address chosen by a
client, with arguments of any type, sent without a model in the registry.
"""

from __future__ import annotations

import heapq
import itertools
from typing import Any

from common.core import Outgoing
from common.messages import Arg, OscMessage


class RedundantScheduler:
    """Holds the copies still to send, in due order. Times are rig seconds."""

    def __init__(self) -> None:
        self._heap: list[tuple[float, int, Outgoing]] = []
        self._order = itertools.count()
        self.copies_sent = 0

    def send(self, outgoing: Outgoing, now: float, copies: int, spacing: float) -> list[Outgoing]:
        """The copies due now (the first, or all when ``spacing`` is 0); the rest wait for :meth:`due`."""
        out = [outgoing]
        for i in range(1, copies):
            if spacing <= 0:
                out.append(outgoing)
            else:
                heapq.heappush(self._heap, (now + i * spacing, next(self._order), outgoing))
        self.copies_sent += len(out)
        return out

    def due(self, now: float) -> list[Outgoing]:
        """Copies whose time has come by rig time ``now``, oldest first."""
        out: list[Outgoing] = []
        heap = self._heap
        while heap and heap[0][0] <= now + 1e-9:
            out.append(heapq.heappop(heap)[2])
        self.copies_sent += len(out)
        return out

    def __len__(self) -> int:
        return len(self._heap)


class RegisteredOut(OscMessage):
    """A message registered at run time; its address is set per registration (see :func:`registered_message`)."""

    ADDRESS = "/batteur/interaction/registered"
    values: tuple[Any, ...] = ()

    def to_args(self) -> list[Arg]:
        return list(self.values)


_CLASSES: dict[str, type[RegisteredOut]] = {}


def registered_message(address: str, args: list[Arg]) -> RegisteredOut:
    """A sendable message for any OSC address with any int/float/str arguments.

    Not in the message registry: a Batteur receiver drops it as an unknown
    address unless a model is registered there; Pd, Max, ossia take it as is.
    """
    cls = _CLASSES.get(address)
    if cls is None:
        if len(_CLASSES) > 4096:  # bounded: addresses come from clients
            _CLASSES.clear()
        cls = type(f"Registered_{len(_CLASSES)}", (RegisteredOut,), {"ADDRESS": address, "__module__": __name__})
        _CLASSES[address] = cls
    return cls(values=tuple(args))
