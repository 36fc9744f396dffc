"""A token bucket: at most ``rate`` events per second, in bursts of up to ``burst``.

Used wherever a remote sender must not be able to make a node work or send without bound: datagrams per source
and answers to undecodable controls (:mod:`common.transport`), copies per subscriber and answers to refused
subscriptions (:mod:`common.subscribe`), answers to refused physics controls (:mod:`services.physics.core`).
"""

from __future__ import annotations

from collections import OrderedDict


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


class TokenBuckets:
    """One :class:`TokenBucket` per key (a sender host), created full when the key is first charged; past
    ``max_keys`` the least recently charged is forgotten, so forged sources cannot grow the table."""

    def __init__(self, rate: float, burst: float, max_keys: int = 1024) -> None:
        self.rate = rate
        self.burst = burst
        self.max_keys = max_keys
        self._buckets: OrderedDict[str, TokenBucket] = OrderedDict()

    def take(self, key: str, now: float, count: float = 1.0) -> bool:
        """Charge ``count`` tokens to ``key``'s bucket at time ``now`` (seconds): :meth:`TokenBucket.take`."""
        bucket = self._buckets.get(key)
        if bucket is None:
            bucket = self._buckets[key] = TokenBucket(self.rate, self.burst, now)
            if len(self._buckets) > self.max_keys:
                self._buckets.popitem(last=False)
        else:
            self._buckets.move_to_end(key)
        return bucket.take(now, count)

    def __len__(self) -> int:
        return len(self._buckets)
