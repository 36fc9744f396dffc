"""The rig clock and the estimate of a node's offset to it.

Rig time is seconds since the rig's epoch (a Unix wall time shared by the
rig). Each node keeps a :class:`RigClock`: its *local* rig time is the wall
clock at start minus the epoch, advanced by the monotonic clock (so it never
jumps when the system clock is stepped). A node whose clock is not the rig's
clock master adds an ``offset`` (seconds, master minus local), estimated by an
NTP-style ping/pong exchange (:class:`~common.messages.ClockPing`,
:class:`~common.messages.ClockPong`) with :class:`OffsetEstimator`.

One sample of the exchange, with ``t0`` the asker's local time at ping send,
``t1`` the master's time at ping receipt, ``t2`` the master's time at pong send
and ``t3`` the asker's local time at pong receipt::

    offset = ((t1 - t0) + (t2 - t3)) / 2      round_trip = (t3 - t0) - (t2 - t1)

Whatever the split of the round trip into its two one-way delays, the true
offset lies in ``[offset - round_trip / 2, offset + round_trip / 2]``. The
estimator keeps the samples with the smallest round trips in a sliding
window and intersects those intervals: the estimate is the intersection's
midpoint and the uncertainty its half-width.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

from common.messages import ClockPing, ClockPong


class RigClock:
    """Seconds since the rig epoch, on a monotonic time base, plus an estimated offset.

    Parameters
    ----------
    epoch : float
        The rig epoch, Unix wall time in seconds. ``None``: now (rig time starts at 0).
    wall : callable -> float
        Wall clock, Unix seconds (read once, at construction). Injectable for tests.
    monotonic : callable -> float
        Monotonic clock, seconds. Injectable for tests.
    """

    def __init__(
        self,
        epoch: float | None = None,
        *,
        wall: Callable[[], float] = time.time,
        monotonic: Callable[[], float] = time.monotonic,
    ) -> None:
        wall_now = wall()
        self.epoch: float = wall_now if epoch is None else float(epoch)
        self._monotonic = monotonic
        self._mono_start = monotonic()
        self._local_start = wall_now - self.epoch
        self.offset: float = 0.0
        """Seconds to add to the local rig time to get the master's rig time."""
        self.synced: bool = False
        """True once the offset comes from an estimate (or the clock is the master)."""

    def local_now(self) -> float:
        """Rig time by this node's own clock, without the offset, seconds."""
        return self._local_start + (self._monotonic() - self._mono_start)

    def now(self) -> float:
        """Rig time, seconds since the epoch: local time plus the estimated offset."""
        return self.local_now() + self.offset

    def to_unix(self, rig_time: float) -> float:
        """Unix wall time (seconds) of a rig time, by this node's wall clock at start."""
        return rig_time - self.offset + self.epoch


def answer_ping(ping: ClockPing, t_receive: float, t_reply: float) -> ClockPong:
    """The clock master's answer to a ping.

    Parameters
    ----------
    ping : ClockPing
        The received ping.
    t_receive : float
        Rig time when the ping arrived, seconds.
    t_reply : float
        Rig time when the pong leaves, seconds.
    """
    return ClockPong(node_id=ping.node_id, seq=ping.seq, t_send=ping.t_send, t_receive=t_receive, t_reply=t_reply)


@dataclass(frozen=True)
class ClockSample:
    """One ping/pong exchange: the offset it implies and its round trip, seconds."""

    seq: int
    offset: float
    round_trip: float
    at: float
    """asker's local time when the pong arrived, seconds"""

    @property
    def low(self) -> float:
        return self.offset - self.round_trip / 2

    @property
    def high(self) -> float:
        return self.offset + self.round_trip / 2


def sample_from_pong(pong: ClockPong, t_arrive: float) -> ClockSample:
    """Offset and round trip of one exchange; ``t_arrive``: local time at pong receipt, seconds."""
    t0, t1, t2, t3 = pong.t_send, pong.t_receive, pong.t_reply, t_arrive
    offset = ((t1 - t0) + (t2 - t3)) / 2
    round_trip = (t3 - t0) - (t2 - t1)
    return ClockSample(seq=pong.seq, offset=offset, round_trip=round_trip, at=t3)


class OffsetEstimator:
    """Estimates the offset of a local clock to the rig clock master from ping/pong samples.

    Parameters
    ----------
    node_id : str
        The asking node's id (pings carry it; pongs for other nodes are ignored).
    window : int
        How many recent samples to keep.
    best : int
        How many of the window's smallest-round-trip samples the estimate uses.
    max_round_trip_s : float
        Samples with a longer round trip (seconds) are discarded.
    """

    def __init__(self, node_id: str, window: int = 32, best: int = 4, max_round_trip_s: float = 1.0) -> None:
        if window < 1 or not 1 <= best <= window:
            raise ValueError("need window >= 1 and 1 <= best <= window")
        self.node_id = node_id
        self.best = best
        self.max_round_trip_s = max_round_trip_s
        self.samples: deque[ClockSample] = deque(maxlen=window)
        self.rejected = 0
        """pongs ignored: unknown sequence number, other node, negative or too long round trip"""
        self._seq = 0
        self._pending: dict[int, float] = {}

    def make_ping(self, t_local: float) -> ClockPing:
        """A new ping sent at local time ``t_local`` (seconds)."""
        seq = self._seq
        self._seq += 1
        self._pending[seq] = t_local
        for old in [s for s in self._pending if s < seq - 64]:
            del self._pending[old]
        return ClockPing(node_id=self.node_id, seq=seq, t_send=t_local)

    def add_pong(self, pong: ClockPong, t_local: float) -> ClockSample | None:
        """Take one pong received at local time ``t_local`` (seconds); the sample, or None if rejected."""
        sent = self._pending.pop(pong.seq, None)
        if pong.node_id != self.node_id or sent is None or not math.isclose(sent, pong.t_send, abs_tol=1e-6):
            self.rejected += 1
            return None
        sample = sample_from_pong(pong, t_local)
        if not 0.0 <= sample.round_trip <= self.max_round_trip_s:
            self.rejected += 1
            return None
        self.samples.append(sample)
        return sample

    def _best_samples(self) -> list[ClockSample]:
        return sorted(self.samples, key=lambda s: s.round_trip)[: self.best]

    @property
    def ready(self) -> bool:
        return bool(self.samples)

    @property
    def offset(self) -> float:
        """Estimated offset, seconds (master minus local). 0 before any sample."""
        return self._estimate()[0]

    @property
    def uncertainty(self) -> float:
        """Half-width of the interval the offset lies in, seconds (inf before any sample)."""
        return self._estimate()[1]

    @property
    def round_trip(self) -> float:
        """Smallest round trip in the window, seconds (inf before any sample)."""
        return min((s.round_trip for s in self.samples), default=math.inf)

    def _estimate(self) -> tuple[float, float]:
        best = self._best_samples()
        if not best:
            return 0.0, math.inf
        low = max(s.low for s in best)
        high = min(s.high for s in best)
        if low <= high:
            return (low + high) / 2, (high - low) / 2
        # intervals disagree (clock drift or a stalled master): trust the shortest round trip
        first = best[0]
        return first.offset, first.round_trip / 2
