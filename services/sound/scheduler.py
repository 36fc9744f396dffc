"""Sample-accurate strike scheduling on the rig clock.

A strike at rig time ``t`` plays at output sample ``round((t + latency - origin) * sr)``
(the latency window hides network jitter, as SuperCollider's server latency
does). A strike whose sample has already been rendered is late: it plays at
the start of the next block and is counted. Impacts are sent redundantly with
the same ``seq`` and time; such copies are dropped and counted. A sender reusing a
``seq`` for another time (a Pd patch sending every strike as seq 0) sends new
impacts, each played, as the Pd sound client (pd/batteur-voice.pd) plays them.
"""

from __future__ import annotations

import heapq
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Generic, TypeVar

T = TypeVar("T")


@dataclass
class Scheduler(Generic[T]):
    """A queue of payloads keyed by output sample index.

    Attributes
    ----------
    sample_rate : float
        Hz.
    latency : float
        Scheduling window, seconds.
    origin : float
        Rig time of output sample 0, seconds.
    late : int
        Strikes that arrived after their sample was rendered (played at once).
    duplicates : int
        Redundant copies dropped (same sender, ``seq`` and rig time).
    """

    sample_rate: float = 48000.0
    latency: float = 0.05
    origin: float = 0.0
    late: int = 0
    duplicates: int = 0
    lateness: list[int] = field(default_factory=list)  # samples late, most recent last (bounded)
    _heap: list[tuple[int, int, T]] = field(default_factory=list)
    _counter: int = 0
    _seen: OrderedDict[tuple[str, int, float], None] = field(default_factory=OrderedDict)
    dedupe_window: int = 8192

    def sample_of(self, rig_time: float) -> int:
        """Output sample index at which an event of rig time ``rig_time`` (seconds) plays."""
        return int(round((rig_time + self.latency - self.origin) * self.sample_rate))

    def is_duplicate(self, source: str, seq: int, rig_time: float) -> bool:
        """True (and counted) when (source, seq, rig_time) was already scheduled: a copy of one message. The time
        is part of the key because a sender that numbers nothing (every strike seq 0) sends distinct events."""
        key = (source, seq, float(rig_time))
        if key in self._seen:
            self.duplicates += 1
            return True
        self._seen[key] = None
        if len(self._seen) > self.dedupe_window:
            self._seen.popitem(last=False)
        return False

    def push(self, rig_time: float, payload: T, next_sample: int) -> int:
        """Queue ``payload``; ``next_sample`` is the first sample not yet rendered. Returns its sample."""
        target = self.sample_of(rig_time)
        if target < next_sample:
            self.late += 1
            self.lateness.append(next_sample - target)
            if len(self.lateness) > 1024:
                del self.lateness[:512]
            target = next_sample
        heapq.heappush(self._heap, (target, self._counter, payload))
        self._counter += 1
        return target

    def pop_until(self, end_sample: int) -> list[tuple[int, T]]:
        """Every queued (sample, payload) with sample < ``end_sample``, in time order."""
        out: list[tuple[int, T]] = []
        while self._heap and self._heap[0][0] < end_sample:
            sample, _, payload = heapq.heappop(self._heap)
            out.append((sample, payload))
        return out

    def __len__(self) -> int:
        return len(self._heap)
