"""Receiver-side de-duplication of redundantly sent messages, by (sender, sequence number).

Interaction sends each impact (and impact end, damping) several times, a
little apart, with the same ``seq`` (ARCHITECTURE.md, interaction routing);
a receiver keeps the first copy and drops the rest::

    dedupe = Deduplicator()
    def handle(message, now, source):
        if isinstance(message, Impact) and not dedupe.accept_message(source, message):
            return []  # a copy of an impact already played

Memory is bounded: each sender keeps its last ``window`` sequence numbers,
and at most ``max_senders`` senders are remembered (least recently heard
forgotten first). A sequence number more than ``window`` below the highest
one seen from that sender means the sender restarted (its counter began
again): the sender's history is cleared and the message accepted.
"""

from __future__ import annotations

from collections import OrderedDict, deque
from dataclasses import dataclass, field

from common.messages import OscMessage


@dataclass
class _SenderWindow:
    highest: int
    seen: set[int] = field(default_factory=set)
    order: deque[int] = field(default_factory=deque)


@dataclass
class DedupeStats:
    """What a :class:`Deduplicator` accepted and dropped since start."""

    accepted: int = 0
    duplicates: int = 0
    restarts: int = 0
    forgotten_senders: int = 0


class Deduplicator:
    """Remembers recent (sender, seq) pairs and tells first copies from repeats.

    Parameters
    ----------
    window : int > 0
        sequence numbers remembered per sender; must exceed the number of
        messages a sender emits while copies of one message are in flight.
    max_senders : int > 0
        senders remembered at once.
    """

    def __init__(self, window: int = 4096, max_senders: int = 256) -> None:
        if window <= 0 or max_senders <= 0:
            raise ValueError("window and max_senders must be positive")
        self.window = window
        self.max_senders = max_senders
        self.stats = DedupeStats()
        self._senders: OrderedDict[str, _SenderWindow] = OrderedDict()

    def accept(self, sender: str, seq: int) -> bool:
        """True the first time ``(sender, seq)`` is seen, False for a repeat."""
        state = self._senders.get(sender)
        if state is None:
            state = _SenderWindow(highest=seq)
            self._senders[sender] = state
            if len(self._senders) > self.max_senders:
                self._senders.popitem(last=False)
                self.stats.forgotten_senders += 1
        else:
            self._senders.move_to_end(sender)
            if seq in state.seen:
                self.stats.duplicates += 1
                return False
            if seq < state.highest - self.window:
                # far older than anything remembered: the sender started counting again
                state.seen.clear()
                state.order.clear()
                state.highest = seq
                self.stats.restarts += 1
        state.seen.add(seq)
        state.order.append(seq)
        if len(state.order) > self.window:
            state.seen.discard(state.order.popleft())
        state.highest = max(state.highest, seq)
        self.stats.accepted += 1
        return True

    def accept_message(self, source: str, message: OscMessage) -> bool:
        """:meth:`accept` keyed on the sender, the message's address and its ``seq`` field.

        Messages without a ``seq`` field are always accepted (and not counted).
        """
        seq = getattr(message, "seq", None)
        if not isinstance(seq, int):
            return True
        return self.accept(f"{source}{message.ADDRESS}", seq)

    def forget(self, sender: str) -> None:
        """Drop what is remembered of one sender (every address when given a bare source)."""
        for key in [k for k in self._senders if k == sender or k.startswith(f"{sender}/")]:
            del self._senders[key]

    def __len__(self) -> int:
        return len(self._senders)
