"""A token bucket: at most ``rate`` events per second, in bursts of up to ``burst``.

Used wherever a remote sender must not be able to make a node work or send without bound: datagrams per source
(:mod:`common.transport`), copies per subscriber and answers to refused subscriptions (:mod:`common.subscribe`).
"""

from __future__ import annotations


class TokenBucket:
    """``rate`` tokens per second (seconds from the caller's clock), holding at most ``burst``; starts full."""

    __slots__ = ("rate", "burst", "tokens", "stamp")

    def __init__(self, rate: float, burst: float, now: float) -> None:
        self.rate = rate
        self.burst = burst
        self.tokens = burst
        self.stamp = now

    def take(self, now: float, count: float = 1.0) -> bool:
        """Charge ``count`` tokens at time ``now`` (seconds) if at least one is there; False (nothing charged)
        otherwise. A charge may take the bucket below zero (a bundle larger than the burst passes once); the
        debt is paid back at ``rate`` before the next charge passes."""
        self.tokens = min(self.burst, self.tokens + max(0.0, now - self.stamp) * self.rate)
        self.stamp = now
        if self.tokens >= 1.0:
            self.tokens -= count
            return True
        return False
