"""Subscriptions: copy the messages a node sends or receives to whoever asked (``batteur echo``).

A :class:`~common.messages.Subscribe` message (pattern + duration) makes the node forward a
copy of every message whose address matches the OSC address pattern to the subscriber's
address (the source of the Subscribe) until the duration has passed. Renewing (same source,
same pattern) extends it. The table is bounded (``max_subscribers``) and each subscriber's
copies are rate limited (``max_rate`` messages per second), so a Subscribe cannot turn a node
into a traffic amplifier; refusals and dropped copies are counted. A refused Subscribe is
answered (:class:`~common.messages.SubscribeRefused`, sent by the node) at most once a second
per source and ``MAX_REFUSAL_REPLY_RATE`` times a second in all, so a flood of bad Subscribes
(from spoofed sources too) makes no flood of replies; the replies held back are counted.

OSC 1.0 address patterns: ``?`` one character, ``*`` any run of characters (never ``/``),
``[abc]``, ``[a-z]``, ``[!abc]`` one character of (or not of) a set, ``{foo,bar}`` one of
several strings. OSC 1.1's ``//`` (any number of levels) is supported too.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import lru_cache

from common.token_bucket import TokenBucket

MAX_SUBSCRIBERS = 16
"""Subscriptions a node keeps at once; further Subscribe requests are refused until one expires."""
MAX_COPY_RATE = 5000.0
"""Copies per second one subscription may receive; more are dropped and counted."""
REFUSAL_REPLY_INTERVAL_S = 1.0
"""Seconds between two answers to the refused Subscribes of one source; the ones between are not answered."""
MAX_REFUSAL_REPLY_RATE = 20.0
"""Answers to refused Subscribes per second, all sources together (burst of as many)."""


class PatternError(ValueError):
    """Not a valid OSC address pattern."""


@lru_cache(maxsize=512)
def pattern_regex(pattern: str) -> re.Pattern[str]:
    """Compile an OSC address pattern to a regular expression matching whole addresses.

    Raises
    ------
    PatternError
        Unbalanced ``[`` or ``{``, or a pattern not starting with ``/``.
    """
    if not pattern.startswith("/"):
        raise PatternError(f"{pattern!r}: an OSC address pattern starts with '/'")
    out: list[str] = []
    i = 0
    n = len(pattern)
    while i < n:
        c = pattern[i]
        if c == "/" and pattern.startswith("//", i):
            out.append("(?:/[^/]*)*/")  # OSC 1.1: any number of levels
            i += 2
        elif c == "*":
            out.append("[^/]*")
            i += 1
        elif c == "?":
            out.append("[^/]")
            i += 1
        elif c == "[":
            end = pattern.find("]", i + 1)
            if end < 0:
                raise PatternError(f"{pattern!r}: '[' without ']'")
            body = pattern[i + 1 : end]
            negate = body.startswith("!")
            if negate:
                body = body[1:]
            if not body:
                raise PatternError(f"{pattern!r}: empty character set")
            chars = "".join("\\" + ch if ch in "\\^]" else ch for ch in body)
            out.append(f"[{'^/' if negate else ''}{chars}]")
            i = end + 1
        elif c == "{":
            end = pattern.find("}", i + 1)
            if end < 0:
                raise PatternError(f"{pattern!r}: '{{' without '}}'")
            options = pattern[i + 1 : end].split(",")
            out.append("(?:" + "|".join(re.escape(o) for o in options) + ")")
            i = end + 1
        else:
            out.append(re.escape(c))
            i += 1
    try:
        return re.compile("".join(out) + r"\Z")
    except re.error as exc:
        raise PatternError(f"{pattern!r}: {exc}") from None


def matches(pattern: str, address: str) -> bool:
    """Whether the OSC ``address`` matches the OSC address ``pattern``."""
    return pattern_regex(pattern).match(address) is not None


@dataclass
class Subscription:
    """One subscriber: where copies go, what it wants, until when (monotonic seconds)."""

    to: tuple[str, int]
    pattern: str
    expires: float
    duration_s: float = 0.0
    """As last asked for: a renewal asking the same is routine (logged quietly), another duration a change."""
    bucket: TokenBucket = field(default_factory=lambda: TokenBucket(MAX_COPY_RATE, MAX_COPY_RATE, 0.0))
    """Copies per second it may receive (:data:`MAX_COPY_RATE`, or the table's ``max_rate``)."""
    sent: int = 0
    dropped: int = 0
    _cache: dict[str, bool] = field(default_factory=dict)

    def wants(self, address: str) -> bool:
        known = self._cache.get(address)
        if known is None:
            known = matches(self.pattern, address)
            if len(self._cache) > 1024:
                self._cache.clear()
            self._cache[address] = known
        return known


class Subscriptions:
    """The subscribers of one node.

    Parameters
    ----------
    send : callable(data, (host, port))
        Sends one copy (already encoded).
    clock : callable -> float
        Monotonic seconds.
    max_subscribers : int
        Subscriptions kept at once; more are refused (``refused``).
    max_rate : float
        Copies per second per subscription; more are dropped (``dropped``).
    """

    def __init__(
        self,
        send: Callable[[bytes, tuple[str, int]], None],
        clock: Callable[[], float],
        max_subscribers: int = MAX_SUBSCRIBERS,
        max_rate: float = MAX_COPY_RATE,
    ) -> None:
        self.send = send
        self.clock = clock
        self.max_subscribers = max_subscribers
        self.max_rate = max_rate
        self.active: dict[tuple[tuple[str, int], str], Subscription] = {}
        self.refused = 0
        """Subscribe requests refused (table full, bad pattern)."""
        self.dropped = 0
        """Copies not sent because a subscriber was over its rate."""
        self.forwarded = 0
        """Copies sent."""
        self.replies = 0
        """Refused Subscribes answered."""
        self.replies_suppressed = 0
        """Refused Subscribes not answered (their source was answered less than a second ago, or too many)."""
        self._replied: dict[tuple[str, int], float] = {}
        self._reply_bucket = TokenBucket(MAX_REFUSAL_REPLY_RATE, MAX_REFUSAL_REPLY_RATE, clock())

    def subscribe(self, to: tuple[str, int], pattern: str, duration_s: float) -> bool:
        """Add or renew a subscription; False if refused (bad pattern or table full)."""
        return not self.request(to, pattern, duration_s)

    def request(self, to: tuple[str, int], pattern: str, duration_s: float) -> str:
        """Add or renew a subscription: "" when done, else why it was refused (bad pattern, table full)."""
        try:
            pattern_regex(pattern)
        except PatternError as exc:
            self.refused += 1
            return f"bad pattern {exc}"
        now = self.clock()
        self.expire(now)
        key = (to, pattern)
        known = self.active.get(key)
        if known is not None:
            known.expires = now + duration_s
            known.duration_s = duration_s
            return ""
        if len(self.active) >= self.max_subscribers:
            self.refused += 1
            return f"table full ({self.max_subscribers} subscriptions)"
        self.active[key] = Subscription(to, pattern, now + duration_s, duration_s,
                                        TokenBucket(self.max_rate, self.max_rate, now))
        return ""

    def is_renewal(self, to: tuple[str, int], pattern: str, duration_s: float) -> bool:
        """Whether a Subscribe of ``pattern`` for ``duration_s`` from ``to`` only renews a live subscription asking
        the same (``batteur echo`` renews every 5 s: not news worth a log line)."""
        known = self.active.get((to, pattern))
        return known is not None and known.expires > self.clock() and known.duration_s == duration_s

    def may_reply(self, to: tuple[str, int]) -> bool:
        """Whether a refusal may be answered to ``to`` now (counted either way): once a second per source, and
        ``MAX_REFUSAL_REPLY_RATE`` a second in all."""
        now = self.clock()
        last = self._replied.get(to)
        if (last is not None and now - last < REFUSAL_REPLY_INTERVAL_S) or not self._reply_bucket.take(now):
            self.replies_suppressed += 1
            return False
        if len(self._replied) >= 2 * MAX_REFUSAL_REPLY_RATE:
            # forget sources answered over a second ago: the total rate bounds the rest
            self._replied = {k: t for k, t in self._replied.items() if now - t < REFUSAL_REPLY_INTERVAL_S}
        self._replied[to] = now
        self.replies += 1
        return True

    def expire(self, now: float | None = None) -> None:
        """Drop the subscriptions whose time is up."""
        now = self.clock() if now is None else now
        for key in [k for k, s in self.active.items() if s.expires <= now]:
            del self.active[key]

    def __bool__(self) -> bool:
        return bool(self.active)

    def offer(self, address: str, packet: Callable[[], bytes], sender: tuple[str, int] | None = None) -> None:
        """Forward one message (its packet built only if someone wants it) to every matching subscriber but its
        ``sender`` (a subscriber knows what it sent: ``batteur echo '/batteur/*'`` got its own renewals back)."""
        if not self.active:
            return
        now = self.clock()
        data: bytes | None = None
        expired = False
        for sub in self.active.values():
            if sub.expires <= now:
                expired = True
                continue
            if sub.to == sender or not sub.wants(address):
                continue
            if not sub.bucket.take(now):
                sub.dropped += 1
                self.dropped += 1
                continue
            if data is None:
                data = packet()
            self.send(data, sub.to)
            sub.sent += 1
            self.forwarded += 1
        if expired:
            self.expire(now)
