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
midpoint and the uncertainty its half-width. A sample whose interval misses the
estimate's (beyond drift) is an outlier and rejected, unless several in a row
agree: then the master's clock really moved and the estimate follows it. A master
says which launch of it answers (:attr:`RigClock.launch`, in every pong): a pong
of another launch than the samples' is a new master at the same address (a
restart), and the window restarts from it at once.

A new offset further than :data:`STEP_S` from the one in use (a new master, the
same master restarted, a node that ran on its own clock meeting its master) is
a *step* of rig time: :meth:`RigClock.set_offset` counts it in
:attr:`RigClock.generation` and returns it, so the node can tell its core
(``clock_stepped``) instead of the core guessing from time going backward, and
logs it once per restart of the estimate (a new master's first pongs may have
long round trips: the quicker ones after move the estimate again, within its
uncertainty, and are no second restart).
"""

from __future__ import annotations

import logging
import math
import secrets
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

from common.messages import ClockPing, ClockPong

log = logging.getLogger("batteur.clock")

STEP_S = 0.1
"""A change of the offset larger than this (seconds) is a step of rig time, not the estimate's tracking (which
moves it by milliseconds: jitter, drift). Above the latency windows, so a core that re-anchors on it does not
re-anchor on noise."""


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
        self.generation: int = 0
        """Steps of rig time so far (see :meth:`set_offset`): a loop can compare it with the one it last saw."""
        self.last_step_s: float = 0.0
        """The latest step, seconds (new rig time minus old, at the same instant); 0 before any."""
        self.steps: int = 0
        """Steps of rig time of a synced clock logged as a WARNING (its master restarted, was replaced or its clock
        moved), one per restart of the estimate: what ``ClockStatus.steps`` reports."""
        self.launch: int = secrets.randbelow(2**31 - 1) + 1
        """This clock's launch, 1 to 2**31 - 1, drawn at random: a master puts it in its pongs
        (:func:`answer_ping`), so its followers tell a restart at the same address from its first pong."""
        self._series: int | None = None
        self._series_synced = False
        self._series_stepped = False

    def set_offset(self, offset: float, master: str = "the clock master", series: int | None = None) -> float:
        """Take a new offset estimate (seconds, master minus local); returns the step of rig time it makes
        (seconds, negative: back) when larger than :data:`STEP_S`, else 0.0. Every step is counted in
        :attr:`generation` (the core must follow it).

        ``series`` says which run of the estimate the offset comes from (:attr:`OffsetEstimator.restarts`: a new
        master, a new launch of it, agreeing outliers); None: each call a run of its own. The first step of a run
        that began on a synced clock (its master restarted or was replaced) is logged once, as a WARNING, and
        counted in :attr:`steps`; later ones of the same run are its estimate narrowing (a new master's first pong
        took long: the quicker ones after move the estimate within its uncertainty), logged at INFO. The steps of
        the first sync are not logged (the node logs it, and a node that ran on its own clock until then was told
        it would jump).
        """
        step = offset - self.offset
        was_synced = self.synced
        self.offset = offset
        self.synced = True
        if series is None or series != self._series:
            self._series, self._series_synced, self._series_stepped = series, was_synced, False
        if abs(step) <= STEP_S:
            return 0.0
        self.generation += 1
        self.last_step_s = step
        if self._series_synced and not self._series_stepped:
            self.steps += 1
            log.warning("rig clock stepped %s %.1f s: the clock master (%s) restarted? (rig time now %.1f s)",
                        "back" if step < 0 else "forward", abs(step), master, self.now())
        elif was_synced:
            log.info("rig clock moved %+.3f s: its new offset estimate to %s narrowed", step, master)
        self._series_stepped = True
        return step

    def local_now(self) -> float:
        """Rig time by this node's own clock, without the offset, seconds."""
        return self._local_start + (self._monotonic() - self._mono_start)

    def now(self) -> float:
        """Rig time, seconds since the epoch: local time plus the estimated offset."""
        return self.local_now() + self.offset

    def to_unix(self, rig_time: float) -> float:
        """Unix wall time (seconds) of a rig time, by this node's wall clock at start."""
        return rig_time - self.offset + self.epoch


def answer_ping(ping: ClockPing, t_receive: float, t_reply: float, launch: int = 0) -> ClockPong:
    """The clock master's answer to a ping.

    Parameters
    ----------
    ping : ClockPing
        The received ping.
    t_receive : float
        Rig time when the ping arrived, seconds.
    t_reply : float
        Rig time when the pong leaves, seconds.
    launch : int
        The master's :attr:`RigClock.launch` (0: not given).
    """
    return ClockPong(node_id=ping.node_id, seq=ping.seq, t_send=ping.t_send, t_receive=t_receive, t_reply=t_reply,
                     launch=launch)


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

    A pong is used only if it answers a ping still pending (same node id, sequence
    number and send time), its master timestamps are in order and its round trip is
    plausible. Once there is an estimate, a sample whose offset interval misses it (by
    more than clock drift since explains) is an *outlier*: rejected and counted, so one
    forged or stray pong cannot move rig time. ``step_after`` consecutive outliers
    that agree with each other mean the master's clock really moved (a restart under
    the same address by a master that does not say its launch, a suspended laptop):
    the window restarts from them. A pong of another launch than the samples' (its
    ``launch``, when given) is a restart of the master at the same address: the
    window restarts from it at once (an answer to a ping older than that launch's
    first answer is rejected: a late pong of the previous run).

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
    tolerance_s : float
        Slack (seconds) before a sample disagreeing with the estimate is an outlier.
    max_drift : float
        Largest rate difference of the two clocks (seconds per second), widening that slack with age.
    step_after : int
        Consecutive agreeing outliers that replace the estimate.
    max_age_s : float
        Samples older than this (seconds, by the newest) are dropped: after the master was away for
        a while, the clocks have drifted and the fresh samples alone say where the master is.
    """

    def __init__(
        self,
        node_id: str,
        window: int = 32,
        best: int = 4,
        max_round_trip_s: float = 1.0,
        tolerance_s: float = 0.001,
        max_drift: float = 1e-3,
        step_after: int = 4,
        max_age_s: float = 60.0,
    ) -> None:
        if window < 1 or not 1 <= best <= window:
            raise ValueError("need window >= 1 and 1 <= best <= window")
        if not (tolerance_s >= 0 and max_drift >= 0 and step_after >= 1 and max_age_s > 0):
            raise ValueError("need tolerance_s >= 0, max_drift >= 0, step_after >= 1 and max_age_s > 0")
        self.node_id = node_id
        self.best = best
        self.max_round_trip_s = max_round_trip_s
        self.tolerance_s = tolerance_s
        self.max_drift = max_drift
        self.step_after = step_after
        self.max_age_s = max_age_s
        self.samples: deque[ClockSample] = deque(maxlen=window)
        self.rejected = 0
        """pongs ignored: unknown sequence number, other node, disordered, too long a round trip, or outliers"""
        self.outliers = 0
        """of ``rejected``: samples that disagreed with the estimate"""
        self.steps = 0
        """times agreeing outliers replaced the estimate (the master's clock moved); ``ClockStatus.steps`` is
        :attr:`RigClock.steps`, the steps of rig time the node logged, whatever restarted the estimate"""
        self.launch = 0
        """launch of the master the samples come from (its pongs' ``launch``; 0: not said, or no sample yet)"""
        self.restarts = 0
        """times the estimate started over: :meth:`reset` (a new master), a new launch or agreeing outliers"""
        self._launch_seq = -1
        self._left: set[int] = set()
        """launches the estimate has left (a restart's old run): a late pong of one is refused, never taken up again
        (a pong of the old run answering a ping reordered past the new run's first answer would step back to it)"""
        self._seq = 0
        self._pending: dict[int, float] = {}
        self._candidates: list[ClockSample] = []

    def reset(self) -> None:
        """Forget every sample and pending ping (a new master: its answers to old pings are stale)."""
        self.samples.clear()
        self._pending.clear()
        self._candidates.clear()
        self.launch, self._launch_seq = 0, -1
        self._left.clear()
        self.restarts += 1

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
        sample = self._checked_sample(pong, t_local)
        if sample is None:
            self.rejected += 1
            return None
        if pong.launch and pong.launch != self.launch:
            if self.samples and (pong.seq < self._launch_seq or pong.launch in self._left):  # a late pong of a
                self.rejected += 1                                                          # previous run
                return None
            if self.launch:
                self._left.add(self.launch)
            self.launch, self._launch_seq = pong.launch, pong.seq
            if self.samples:  # the master restarted at the same address: follow it now, not after agreeing outliers
                self._restart([sample])
                return sample
        if self._agrees(sample):
            self._candidates.clear()
            self.samples.append(sample)
            while sample.at - self.samples[0].at > self.max_age_s:
                self.samples.popleft()
            return sample
        return self._outlier(sample)

    def _checked_sample(self, pong: ClockPong, t_local: float) -> ClockSample | None:
        """The sample of a pong answering a pending ping, plausible on its own; else None."""
        sent = self._pending.get(pong.seq)
        # a pong that does not match leaves the ping pending: a stray one must not void the real answer
        if pong.node_id != self.node_id or sent is None or not math.isclose(sent, pong.t_send, abs_tol=1e-6):
            return None
        del self._pending[pong.seq]
        if pong.t_reply < pong.t_receive - 1e-6:  # the master answered before it was asked: not a master's pong
            return None
        sample = sample_from_pong(pong, t_local)
        if not (0.0 <= sample.round_trip <= self.max_round_trip_s and math.isfinite(sample.offset)):
            return None
        return sample

    def _agrees(self, sample: ClockSample) -> bool:
        """True if the sample's interval meets that of every sample the estimate uses, each widened by
        the tolerance and by the drift its age allows (so the true offset lies in all of them)."""
        return all(
            _overlap(sample, s, self.tolerance_s + self.max_drift * abs(sample.at - s.at))
            for s in self._best_samples()
        )

    def _outlier(self, sample: ClockSample) -> ClockSample | None:
        """Count an outlier; the sample if it completes ``step_after`` agreeing ones (the window restarts)."""
        if self._candidates and not all(_overlap(sample, c, self.tolerance_s) for c in self._candidates):
            self._candidates.clear()
        self._candidates.append(sample)
        if len(self._candidates) < self.step_after:
            self.rejected += 1
            self.outliers += 1
            return None
        self._restart(self._candidates)
        self.steps += 1
        return sample

    def _restart(self, samples: list[ClockSample]) -> None:
        """Start the window over from ``samples`` (the master's clock moved)."""
        self.samples.clear()
        self.samples.extend(samples)
        self._candidates.clear()
        self.restarts += 1

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


def _overlap(a: ClockSample, b: ClockSample, slack_s: float) -> bool:
    """True if the offset intervals of two samples meet, allowing ``slack_s`` seconds."""
    return a.low - slack_s <= b.high and b.low - slack_s <= a.high
