"""The service runtime: a :class:`Node` runs one core live over UDP.

A node opens a :class:`~common.transport.UdpEndpoint`, fills its
:class:`~common.peers.PeerTable` from static peers and zeroconf discovery,
steps its core at the core's rate on a fixed-rate loop (absolute deadlines, so
it does not drift; overruns are counted, never hidden), hands every received
message to ``core.handle`` (but another service's controls, which its core would
ignore: dropped as ``wrong_node``, see :func:`common.transport.taken_elsewhere`, and answered with the node's
refusal) and routes what
the core returns. It also keeps the
rig clock (answering pings, within a budget per sender; estimating its offset to the clock master when the
master is another node), greets newly found peers with a Hello, answers a Hello
with its Health (within a budget per sender host), publishes Health to every peer
at 1 Hz, and stops cleanly on SIGINT/SIGTERM.

A service's ``node.py`` is a few lines (see docs/runtime.md)::

    from common.runtime import run_node
    from services.sound.core import SoundCore

    def main(argv=None) -> int:
        return run_node("sound", lambda settings, args: SoundCore(latency_s=settings.latency_s), argv)
"""

from __future__ import annotations

import argparse
import asyncio
import collections
import concurrent.futures
import contextlib
import gc
import inspect
import json
import logging
import math
import signal
import struct
import sys
import threading
import time
from collections.abc import Awaitable, Callable, Coroutine, Sequence
from typing import Any, Protocol, cast

from common.arg_types import take_negative_values
from common.clock import OffsetEstimator, RigClock, answer_ping
from common.config import ENV_PREFIX, ConfigFileError, NodeSettings, SettingsError, flag_name, load_settings
from common.core import Core, Outgoing
from common.exit_status import FAILED, USAGE, InputError, report_error
from common.messages import (
    PROTOCOL_VERSION,
    ClockPing,
    ClockPong,
    ClockStatus,
    DropReason,
    Health,
    Hello,
    MessageError,
    OscMessage,
    RawMessage,
    Subscribe,
    SubscribeRefused,
    encode,
)
from common.messages.system import TOOL_ROLE
from common.peers import Peer, PeerTable
from common.rated_log import RatedWarnings
from common.subscribe import Subscriptions
from common.token_bucket import TokenBuckets
from common.transport import (
    DECODE_REPLY_BURST,
    DECODE_REPLY_RATE_HZ,
    SERVICE_ROLES,
    UdpEndpoint,
    format_address,
    parse_address,
    same_ip,
    service_refusal,
    taken_elsewhere,
)

log = logging.getLogger("batteur.runtime")

DEFAULT_BROWSE_ROLES = SERVICE_ROLES
START_UNCERTAINTY_S = 0.005
"""A node whose clock master is another node starts its core once its offset is known to this, seconds (or after
:data:`FAST_PING_SAMPLES` samples, the best it will get soon): the first sample of a loaded machine can be off by
tens of milliseconds, and the core would play that much early or late until better ones came."""
FAST_PING_SAMPLES = 8
"""Clock samples gathered with fast pings (10 Hz) before pinging every ``ping_interval_s``."""
"""Roles a node looks for by default (it publishes Health to all of them)."""
MASTER_SILENT_WARN_S = 30.0
"""A clock master this node knows (a static peer, or one discovery found) that has not answered its pings this long
after the node started is warned about, seconds; until then it is taken to be still starting (physics builds its
scene for about 3 s, 7-15 s on a loaded machine, while a rig's other nodes wait for it)."""
PEER_SILENT_HEALTHS = 5
"""A peer whose Health (sent every health interval, 1 s) has not come for this many intervals is said to have stopped
answering, once, and said to be back when its next Health comes: a service killed and restarted mid-set was silent
in the others' logs (7 Dec walkthrough: still "peers 3")."""
REFUSAL_LOG_INTERVAL_S = 5.0
"""A refused Subscribe (table full, bad pattern) is logged at most once per this long, seconds; the rest are counted
(Health's ``dropped_other``) and said as "+N more" in the next warning."""
HELLO_ANSWER_RATE_HZ = DECODE_REPLY_RATE_HZ
"""Hellos answered per second to one sender host (Health; a tool's also ClockStatus; physics' core also its
Skeleton), past :data:`HELLO_ANSWER_BURST`: the rest are dropped unanswered, counted as ``rate_limited`` (Health's
``dropped_other``). A Hello is ~60 bytes and its answers several times that, and one datagram can bundle a thousand:
unbudgeted, a forged source made a node a reflector (one 60 kB bundle of Hellos drew 376 kB). The undecodable
controls' figures, in a budget of its own, so a flood of bad controls does not silence the Hello of a ``batteur ls``
that would show them counted. The rig asks every 0.5 s until answered, ``batteur ls`` once, peers once when found."""
HELLO_ANSWER_BURST = DECODE_REPLY_BURST
DISCOVERY_OFF, DISCOVERY_ON, DISCOVERY_STARTING, DISCOVERY_FAILED = 0, 1, 2, 3
"""Health's ``discovery``: off (``--no-discovery``), on, starting (registering), failed to start."""
"""Hellos answered to one sender host at once before :data:`HELLO_ANSWER_RATE_HZ`."""
WRONG_NODE_REPLY_RATE_HZ = DECODE_REPLY_RATE_HZ
"""Controls of another service (``wrong_node``) answered with this node's refusal per second to one sender host, past
:data:`WRONG_NODE_REPLY_BURST`; the rest are dropped as before, unanswered (``wrong_node_unanswered``): the undecodable
controls' figures, in a budget of its own, so a forged source cannot make a node a reflector."""
WRONG_NODE_REPLY_BURST = DECODE_REPLY_BURST
"""Controls of another service answered to one sender host at once before :data:`WRONG_NODE_REPLY_RATE_HZ`."""
PONG_ADDRESS_RATE_HZ = 25.0
"""Clock pings answered per second to one sender address (``host:port``: a node pings from its one socket), past
:data:`PONG_ADDRESS_BURST`; the rest are dropped unanswered, counted as ``rate_limited`` (Health's ``dropped_other``).
A pong is 1.5 times its ping (three rig times where the ping has one) and one datagram bundles over a thousand
pings: unbudgeted, a 65 kB bundle drew 1259 pongs, 91 kB (1.9x on the wire), and single pings were answered as fast
as they came. A node pings at 10 Hz until it has 8 samples (again after a new master), then at 1 Hz (tests: 20 Hz); a
script as in docs/live-control.md sends 8 in a row: 2.5 times a node's fastest, so a real client never loses a pong."""
PONG_ADDRESS_BURST = 25.0
"""Clock pings answered to one sender address at once before :data:`PONG_ADDRESS_RATE_HZ`."""
PONG_HOST_RATE_HZ = 100.0
"""Clock pings answered per second to one sender host, all its addresses together, past :data:`PONG_HOST_BURST`:
four clients at their fastest (a rig's interaction, sound and graphics nodes and a client program on one machine,
fast pings all at once after a master restart) within it, and a flood of forged ports of one host cut to it (at
most 100 pongs a second, 10 kB on the wire, whatever is sent). The address budget is charged first: one address over
its own budget takes nothing of its host's, so the other clients of a host flooding from one socket keep their
pongs."""
PONG_HOST_BURST = 100.0
"""Clock pings answered to one sender host at once before :data:`PONG_HOST_RATE_HZ`."""


class PongBudget:
    """Clock pings answered per sender: each address (``host:port``) within its own budget
    (:data:`PONG_ADDRESS_RATE_HZ`), its host, all addresses together, within a larger one (:data:`PONG_HOST_RATE_HZ`).
    Read when made (tests change the constants)."""

    def __init__(self) -> None:
        self._addresses = TokenBuckets(PONG_ADDRESS_RATE_HZ, PONG_ADDRESS_BURST)
        self._hosts = TokenBuckets(PONG_HOST_RATE_HZ, PONG_HOST_BURST)

    def take(self, host: str, address: str, now: float) -> bool:
        """Charge one pong to ``address`` and its ``host`` at time ``now`` (seconds); False if either is over its
        budget. The address first: a ping over its address's budget charges nothing to the host's, so a flood from
        one socket leaves the host's other clients their pongs."""
        return self._addresses.take(address, now) and self._hosts.take(host, now)


# --------------------------------------------------------------------------- fixed-rate loop


class _Sleeper:
    """Sleeps until a monotonic deadline with sub-millisecond precision without blocking the loop.

    asyncio's own timers wake up to 1 ms late (epoll's resolution), a whole
    period at 1 kHz; the last stretch is slept in a helper thread instead.
    """

    def __init__(self) -> None:
        self._pool: concurrent.futures.ThreadPoolExecutor | None = None

    async def __call__(self, deadline: float) -> None:
        remaining = deadline - time.monotonic()
        if remaining > 0.002:
            await asyncio.sleep(remaining - 0.0015)
            remaining = deadline - time.monotonic()
        if remaining > 0:
            if self._pool is None:
                self._pool = concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix="batteur-sleep")
            await asyncio.get_running_loop().run_in_executor(self._pool, time.sleep, remaining)
        else:
            await asyncio.sleep(0)  # let the loop handle I/O between back-to-back ticks

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=False)
            self._pool = None


class RateLoop:
    """Calls ``tick()`` at ``rate_hz`` on absolute deadlines ``start + n / rate_hz``.

    Deadlines never drift with tick duration or wake-up lateness. A tick that
    ends after the next deadline counts as an overrun, and the loop runs the
    next tick at once. When it is more than ``max_catch_up`` whole periods
    behind, the deadlines beyond that are skipped (and counted in ``skipped``):
    a short stall is caught up with back-to-back ticks, a long one or an
    overloaded core gets fewer ticks, never a silently lower rate.

    :meth:`set_rate` changes the rate from the deadline after the next tick on
    (the grid is re-anchored on that tick's deadline, so nothing drifts or
    bursts); :meth:`stop` ends :meth:`run` before the next tick, and after a
    :meth:`set_rate` ``run`` may be awaited again (the counts go on).

    Parameters
    ----------
    rate_hz : float
        Ticks per second, Hz.
    tick : callable
        Called once per period.
    clock : callable -> float
        Monotonic seconds. Injectable for tests.
    sleep_until : async callable(deadline)
        Waits until ``clock() >= deadline``. Injectable for tests.
    max_catch_up : int
        Missed periods caught up with back-to-back ticks before the rest are skipped.
    """

    def __init__(
        self,
        rate_hz: float,
        tick: Callable[[], None],
        *,
        clock: Callable[[], float] = time.monotonic,
        sleep_until: Callable[[float], Awaitable[None]] | None = None,
        max_catch_up: int = 0,
    ) -> None:
        if rate_hz <= 0:
            raise ValueError("rate_hz must be positive")
        self.max_catch_up = max(0, max_catch_up)
        self.rate_hz = rate_hz
        self.period = 1.0 / rate_hz
        self._new_rate: tuple[float, int] | None = None
        self._stop = False
        self.running = False
        """True while :meth:`run` is ticking."""
        self.tick = tick
        self.clock = clock
        self._sleeper = _Sleeper() if sleep_until is None else None
        self.sleep_until: Callable[[float], Awaitable[None]] = sleep_until or cast(_Sleeper, self._sleeper)
        self.ticks = 0
        """ticks run"""
        self.overruns = 0
        """ticks that ended after the next deadline"""
        self.skipped = 0
        """deadlines skipped because the loop was a whole period or more behind"""
        self._mark = (0.0, 0)

    def set_rate(self, rate_hz: float, max_catch_up: int | None = None) -> None:
        """Tick at ``rate_hz`` (Hz, positive and finite) once the next tick has run; cancels a :meth:`stop`."""
        if not (math.isfinite(rate_hz) and rate_hz > 0):
            raise ValueError(f"rate_hz must be positive and finite, got {rate_hz!r}")
        self._new_rate = (rate_hz, self.max_catch_up if max_catch_up is None else max(0, max_catch_up))
        self._stop = False
        if not self.running:
            self._apply_new_rate()

    def stop(self) -> None:
        """End :meth:`run` before its next tick (an event-driven core: rate 0)."""
        self._stop = True

    def _apply_new_rate(self) -> None:
        if self._new_rate is not None:
            self.rate_hz, self.max_catch_up = self._new_rate
            self.period = 1.0 / self.rate_hz
            self._new_rate = None

    async def run(self, max_ticks: int | None = None) -> None:
        """Tick until cancelled, stopped (:meth:`stop`) or ``max_ticks`` ticks in all."""
        start = self.clock()
        if self.ticks == 0:
            self._mark = (start, 0)
        n = 0
        self.running = True
        try:
            while max_ticks is None or self.ticks < max_ticks:
                await self.sleep_until(start + n * self.period)
                if self._stop:
                    break
                self.tick()
                self.ticks += 1
                n += 1
                if self._stop:
                    break
                if self._new_rate is not None:  # re-anchor on the deadline of the tick just run
                    start, n = start + (n - 1) * self.period, 1
                    self._apply_new_rate()
                end = self.clock()
                next_deadline = start + n * self.period
                if end > next_deadline:
                    self.overruns += 1
                    skip = int((end - next_deadline) / self.period) - self.max_catch_up
                    if skip > 0:
                        n += skip
                        self.skipped += skip
        finally:
            self.running = False
            self._apply_new_rate()  # a change asked for during the last tick
            if self._sleeper is not None:
                self._sleeper.close()

    def achieved_rate(self) -> float:
        """Ticks per second since the previous call (or the start), Hz."""
        now = self.clock()
        since, ticks = self._mark
        self._mark = (now, self.ticks)
        return (self.ticks - ticks) / (now - since) if now > since else 0.0


# --------------------------------------------------------------------------- discovery


class DiscoveryService(Protocol):
    """What the node needs from discovery (``common.discovery.Discovery``)."""

    async def start(self) -> None: ...

    async def stop(self) -> None: ...


DiscoveryFactory = Callable[..., DiscoveryService]
"""Called with keywords role, node_id, port, interfaces, peers, browse_roles, protocol."""


def default_discovery_factory(**kwargs: Any) -> DiscoveryService | None:
    """``common.discovery.Discovery(**kwargs)``, or None (with a warning) if it is not available."""
    try:
        from common.discovery import Discovery
    except ImportError as exc:
        log.warning("discovery is not available (%s); using static peers only", exc)
        return None
    return cast(DiscoveryService, Discovery(**kwargs))


def check_interfaces(interfaces: Sequence[str]) -> str:
    """Why discovery cannot use these interfaces ("" if it can, or if discovery is not installed)."""
    try:
        from common.discovery import resolve_interfaces
    except ImportError:
        return ""
    try:
        resolve_interfaces(list(interfaces))
    except Exception as exc:
        return str(exc)
    return ""


def loopback_announce_problem(host: str, interfaces: Sequence[str]) -> str:
    """Why other machines cannot find a node that listens for them ("" if they can, or it listens on loopback): it
    listens on every address (``--host 0.0.0.0``) or a LAN one, but announces itself (zeroconf) on loopback only, the
    default without ``--interface``. A teacher's sound laptop started so was found by no one, said only by an INFO
    line (``on ['127.0.0.1']``), a warning 30 s later, and the other laptop's ``no sound peer known`` once a minute;
    said at start, with the fix and this machine's other interfaces."""
    from common.config import is_loopback

    if is_loopback(host):
        return ""
    try:
        import ifaddr

        from common.discovery import is_loopback as is_loopback_address
        from common.discovery import resolve_interfaces

        addresses = resolve_interfaces(list(interfaces))
        adapters = list(ifaddr.get_adapters())
    except Exception:  # noqa: BLE001 - no discovery installed, or interfaces it refuses (refused at start already)
        return ""
    if not addresses or not all(is_loopback_address(a) for a in addresses):
        return ""
    lan = [f"{a.nice_name} ({ip.ip})" for a in adapters for ip in a.ips
           if isinstance(ip.ip, str) and not is_loopback_address(ip.ip)]
    listens = "on every address" if host in ("0.0.0.0", "::") else f"on {host}"
    return (f"this node listens {listens} but announces itself (zeroconf) on loopback only ({', '.join(addresses)}): "
            "nodes on other machines will not find it, nor it them. Give the interface of the network they are on: "
            f"--interface NAME or ADDRESS (BATTEUR_INTERFACES; this machine's: {', '.join(lan) or 'none but loopback'})"
            ", or static peers (--peer ROLE=HOST:PORT)")


# --------------------------------------------------------------------------- node

Setup = Callable[["Node"], Awaitable[None] | None]
"""Called with the node once it listens (may be async)."""


def wrong_node_refusal(role: str, address: str, reason: str) -> OscMessage | None:
    """The refusal a node of the service ``role`` answers a control of another service at ``address`` with: its own
    service's (/batteur/physics/rejected, /batteur/sound/rejected, /batteur/interaction/error,
    /batteur/graphics/rejected), naming ``address`` and ``reason`` (clipped to 512 characters); None for a role
    with no refusal message."""
    return service_refusal(role, address, _clip(reason, 512))


def _clip(text: str, length: int) -> str:
    """``text`` cut to ``length`` characters (an ellipsis at the end when cut)."""
    return text if len(text) <= length else text[: length - 3] + "..."


def _same_number(a: object, b: object) -> bool:
    """``a == b``, NaN equal to NaN (a core's rate that stays NaN is refused once, not at every step)."""
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    try:
        return bool(a == b)
    except Exception:
        return False


def _or_minus_one(value: float) -> float:
    """``value``, or -1 when it is not finite (no estimate yet: OSC carries no infinity)."""
    return value if math.isfinite(value) else -1.0


def core_count(core: object, name: str) -> int:
    """A core's optional running total ``name`` (0 when it has none, or holds something that is not a count)."""
    try:
        return max(0, int(getattr(core, name, 0) or 0))
    except (TypeError, ValueError):
        return 0


def core_seconds(core: object, name: str) -> float:
    """A core's optional duration ``name``, seconds (0 when it has none, or holds something that is not a finite
    duration of at least 0)."""
    try:
        value = float(getattr(core, name, 0.0) or 0.0)
    except (TypeError, ValueError):
        return 0.0
    return value if math.isfinite(value) and value > 0.0 else 0.0


class Node:
    """Runs one core live: transport, peers, discovery, fixed-rate stepping, clock, health.

    Parameters
    ----------
    core : Core
        The service core to run.
    settings : NodeSettings
        Where to listen, peers, discovery, rate, clock master...
    discovery_factory : callable or None
        Builds the discovery service (keywords: role, node_id, port, interfaces,
        peers, browse_roles, protocol, allowed: the transport's allow-list as strings,
        None on loopback). Default: ``common.discovery.Discovery``.
        Ignored when ``settings.discovery`` is off.
    browse_roles : sequence of str
        Roles to look for with discovery.
    health_interval_s, ping_interval_s : float
        Health publication period and clock ping period (once synced), seconds.
    max_catch_up_s : float
        After a stall, up to this much of missed steps is caught up back to back
        (10 ticks at 1 kHz, none at 60 Hz); the rest is skipped. Seconds.
    clock_wait_s : float
        A node whose clock master is another node holds its core (no steps; messages for the
        core queued, up to 1024) until its clock offset is estimated to :data:`START_UNCERTAINTY_S`
        (or from :data:`FAST_PING_SAMPLES` samples), so the core never sees rig time jump by the
        offset; after this long it starts anyway (on the estimate so far, or without a master on its
        own clock). Seconds.
    """

    def __init__(
        self,
        core: Core,
        settings: NodeSettings,
        *,
        discovery_factory: DiscoveryFactory | None = None,
        browse_roles: Sequence[str] = DEFAULT_BROWSE_ROLES,
        clock: RigClock | None = None,
        health_interval_s: float = 1.0,
        ping_interval_s: float = 1.0,
        max_catch_up_s: float = 0.01,
        clock_wait_s: float = 3.0,
    ) -> None:
        self.core = core
        self.settings = settings
        self.role = settings.role
        self.node_id = settings.node_id
        self.rate_hz = settings.rate_hz if settings.rate_hz is not None else float(core.rate_hz)
        if not (math.isfinite(self.rate_hz) and self.rate_hz >= 0):  # inf: a busy loop; NaN: no loop, bad Health
            raise ValueError(f"{settings.role}: rate {self.rate_hz!r} Hz is not a rate (0 or more Hz, finite)")
        if settings.rate_hz is not None:
            try:
                core.rate_hz = settings.rate_hz
            except AttributeError:
                pass
        self._service = str(getattr(core, "ROLE", "") or "")
        """The service whose core this node runs (its handlers'; ``--role`` names the node): what it takes."""
        self._core_rate_seen: object = getattr(core, "rate_hz", None)
        """The core's rate_hz when last looked at (:meth:`follow_core_rate`)."""
        self.clock = clock or RigClock(settings.epoch)
        self.peers = PeerTable()
        self.discovery_factory = discovery_factory
        self.browse_roles = list(dict.fromkeys([*browse_roles, *self._master_roles()]))
        self.health_interval_s = health_interval_s
        self.ping_interval_s = ping_interval_s
        self.max_catch_up_s = max_catch_up_s
        self._achieved_rate = 0.0
        self._master_id = ""
        self._ping_to: tuple[str, int] | None = None
        """Where the clock pings go (the master's host and port as the peer table has them); pongs must come from
        there."""
        self.foreign_pongs = 0
        """Clock pongs dropped because they came from elsewhere than the master's address."""
        self.estimator = OffsetEstimator(self.node_id)
        self.endpoint: UdpEndpoint | None = None
        self.loop: RateLoop | None = None
        self._loop_task: asyncio.Task[Any] | None = None
        self.discovery: DiscoveryService | None = None
        self.discovery_state = DISCOVERY_OFF
        """Health's ``discovery``: off, starting, on, or failed to start (the rig's ready line says so)."""
        self._masters_warned: set[frozenset[str]] = set()
        """The sets of clock masters (node ids) already warned about (:meth:`_warn_two_masters`)."""
        self._last_pong_at = -math.inf
        """When the clock master last answered a ping (``time.monotonic()``): it still answers (discovery)."""
        self.peer_health: dict[str, tuple[Health, str, float]] = {}
        """Last Health heard from each node id: (message, source, local monotonic time)."""
        self.silent_peers: set[str] = set()
        """Node ids of the peers said to have stopped answering (:meth:`_note_silent_peers`), until their Health."""
        self.step_errors = 0
        self.failed = False
        """True if one of the node's tasks failed (the node then stops)."""
        self.stopped = asyncio.Event()
        self._stop_requested: asyncio.Event | None = None
        self._stop_early = False
        """A stop asked for before :meth:`run` bound the loop."""
        self._tasks: list[asyncio.Task[Any]] = []
        self._aio_loop: asyncio.AbstractEventLoop | None = None
        self._loop_thread = 0
        self._last_error_log = 0.0
        self._failures_logged: set[tuple[str, str]] = set()  # (where, exception type) logged with a traceback
        self.clock_wait_s = clock_wait_s
        self.core_started = self.is_clock_master
        """False while a non-master node waits for its clock offset (see ``clock_wait_s``)."""
        self._held: collections.deque[tuple[OscMessage, str]] = collections.deque(maxlen=1024)
        self._started_at = time.monotonic()
        self.subscriptions = Subscriptions(self._send_copy, time.monotonic)
        """Who asked for copies of which messages (:class:`~common.messages.Subscribe`)."""
        self._refusal_warnings = RatedWarnings(log, REFUSAL_LOG_INTERVAL_S)
        """Refused Subscribes: one warning per :data:`REFUSAL_LOG_INTERVAL_S`, the others counted in it."""
        self._hello_budgets = TokenBuckets(HELLO_ANSWER_RATE_HZ, HELLO_ANSWER_BURST)
        """Sender host -> its budget of Hellos answered (:data:`HELLO_ANSWER_RATE_HZ`), on ``time.monotonic``."""
        self._pong_budget = PongBudget()
        """Clock pings answered per sender address and host (:data:`PONG_ADDRESS_RATE_HZ`), on ``time.monotonic``."""
        self._wrong_node_budgets = TokenBuckets(WRONG_NODE_REPLY_RATE_HZ, WRONG_NODE_REPLY_BURST)
        """Sender host -> its budget of refusals of another service's controls (:meth:`_refuse_wrong_node`)."""
        self.wrong_node_unanswered = 0
        """Controls of another service dropped without the refusal: their sender host was over its budget (Health's
        ``wrong_node_unanswered``)."""
        self.oscquery: Any = None
        """The OSCQuery server (``common.oscquery.OscQueryServer``) once started, or None."""
        if self.is_clock_master:
            self.clock.synced = True

    def _master_roles(self) -> list[str]:
        return [] if self.is_clock_master else [self.settings.clock_master]

    @property
    def is_clock_master(self) -> bool:
        """True when this node's clock is the rig clock."""
        return self.settings.clock_master in ("self", self.role)

    # ------------------------------------------------------------ lifecycle

    async def start(self) -> None:
        """Open the endpoint, add static peers, start discovery and the node's tasks."""
        self._bind_loop()
        s = self.settings
        if s.discovery:  # from the first Health on (a Hello is answered while OSCQuery and discovery start)
            self.discovery_state = DISCOVERY_STARTING
        self.endpoint = await UdpEndpoint.open(
            s.host,
            s.port,
            self.peers,
            max_datagram=s.max_datagram,
            allow=s.allow_networks,
            max_rate=s.max_rate,
            role=self.role,
        )
        self.endpoint.set_handler(self._on_message)
        self.endpoint.absent_roles = set(s.absent)
        self.endpoint.tap = self._tap
        self.endpoint.on_undecodable = self._on_undecodable
        if s.oscquery:
            await self._start_oscquery()
        self.peers.listeners.append(self._on_peer_change)
        for peer in s.static_peers:
            self.peers.add(peer)
        self.follow_core_rate()
        self._start_loop()
        self.spawn(self._health_task(), "health")
        if not self.is_clock_master:
            self.spawn(self._clock_task(), "clock")
            self.spawn(self._core_start_timer(), "core start")
        if s.discovery:  # registration probes for about a second; the node already runs meanwhile
            problem = loopback_announce_problem(s.host, s.interfaces)
            if problem:
                log.warning("%s", problem)
            self.discovery_state = DISCOVERY_STARTING
            factory = self.discovery_factory or default_discovery_factory
            self.discovery = factory(
                role=self.role,
                node_id=self.node_id,
                port=self.endpoint.port,
                interfaces=list(s.interfaces),
                peers=self.peers,
                browse_roles=list(self.browse_roles),
                protocol=PROTOCOL_VERSION,
                # the transport's allow-list: a peer it would drop (not_allowed) is not added, and said why once
                allowed=None if s.allow_networks is None else [str(n) for n in s.allow_networks],
                rig=s.rig,
                ttl_s=s.discovery_ttl_s,
                # a peer whose mDNS records expire unanswered (multicast filtered) is kept while it answers here
                still_answers=self.still_answers,
            )
            if self.discovery is not None:
                register_extra = getattr(self.discovery, "register_extra", None)
                if self.oscquery is not None and callable(register_extra):
                    from common.oscquery import SERVICE_TYPE as OSCJSON

                    await register_extra(OSCJSON, self.oscquery.port, self.oscquery.txt())
                try:
                    await self.discovery.start()
                    self.discovery_state = DISCOVERY_ON
                except Exception as exc:  # the node still works with static peers
                    # said in Health too: batteur rig's ready line names the node (a walkthrough's rig said "ready"
                    # while two of its nodes could find no sound node on the other laptop)
                    self.discovery_state = DISCOVERY_FAILED
                    log.error("discovery failed to start (%s); using static peers only: no node on another machine "
                              "is found", exc)
                    with contextlib.suppress(Exception):
                        await asyncio.wait_for(self.discovery.stop(), timeout=2.0)
                    self.discovery = None
            else:
                self.discovery_state = DISCOVERY_FAILED
        log.info(
            "%s node %s listening on %s (rate %g Hz, clock %s, discovery %s)",
            self.role,
            self.node_id,
            self.endpoint.local_address,
            self.rate_hz,
            "master" if self.is_clock_master else f"from {self.settings.clock_master}",
            "on" if self.discovery is not None else "off",
        )

    async def _start_oscquery(self) -> None:
        """Serve the namespace over OSCQuery on the node's host (a failure leaves the node running without it)."""
        from common.oscquery import OscQueryServer

        assert self.endpoint is not None
        endpoint = self.endpoint
        server = OscQueryServer(self.node_id, self.role, self.settings.host, endpoint.port,
                                receive=endpoint.receive_datagram, allow=self.settings.allow_networks)
        try:
            await server.start(self.settings.host, self.settings.oscquery_port)
        except OSError as exc:
            log.error("OSCQuery server cannot listen on %s:%d (%s); running without it",
                      self.settings.host, self.settings.oscquery_port, exc.strerror or exc)
            return
        self.oscquery = server

    def _bind_loop(self) -> None:
        if self._stop_requested is None:
            self._aio_loop = asyncio.get_running_loop()
            self._loop_thread = threading.get_ident()
            self._stop_requested = asyncio.Event()
            if self._stop_early:  # asked before the loop existed (a signal while the node was being made)
                self._stop_requested.set()

    def spawn(self, coro: Coroutine[Any, Any, Any], name: str = "task") -> asyncio.Task[Any]:
        """Run ``coro`` alongside the node; it is cancelled at shutdown, and its failure stops the node."""
        task = asyncio.get_running_loop().create_task(coro, name=name)
        task.add_done_callback(self._task_done)
        self._tasks.append(task)
        return task

    def _task_done(self, task: asyncio.Task[Any]) -> None:
        if task.cancelled():
            return
        exc = task.exception()
        if exc is not None:
            log.error("%s failed: %s: %s", task.get_name(), type(exc).__name__, exc, exc_info=exc)
            self.failed = True
            self.request_stop()

    def request_stop(self) -> None:
        """Ask :meth:`run` to shut down (safe from signal handlers and other threads); asked before :meth:`run`, it
        stops at once without starting."""
        if self._stop_requested is None or self._aio_loop is None:
            self._stop_early = True
            return
        if threading.get_ident() == self._loop_thread:
            self._stop_requested.set()
        else:
            self._aio_loop.call_soon_threadsafe(self._stop_requested.set)

    async def wait_stop_requested(self) -> None:
        assert self._stop_requested is not None
        await self._stop_requested.wait()

    async def stop(self) -> None:
        """Cancel the tasks, close the endpoint and the core, then stop discovery and OSCQuery (idempotent).

        The core closes first: what it writes (a recording) is then whole even if the process is killed while
        discovery says goodbye (up to 2 s each)."""
        if self.stopped.is_set():
            return
        for task in self._tasks:
            task.cancel()
        await asyncio.gather(*self._tasks, return_exceptions=True)
        self._tasks.clear()
        if self.endpoint is not None:
            self.endpoint.close()
        close = getattr(self.core, "close", None)
        if callable(close):
            try:
                close()
            except Exception as exc:
                log.warning("core close failed: %s", exc)
        if self.discovery is not None:
            try:
                await asyncio.wait_for(self.discovery.stop(), timeout=2.0)
            except Exception as exc:
                log.warning("discovery did not stop cleanly: %s", exc)
            self.discovery = None
        if self.oscquery is not None:
            try:
                await asyncio.wait_for(self.oscquery.stop(), timeout=2.0)
            except Exception as exc:
                log.warning("OSCQuery server did not stop cleanly: %s", exc)
            self.oscquery = None
        self.stopped.set()
        log.info("%s node %s stopped", self.role, self.node_id)

    async def run(self, install_signal_handlers: bool = False, setup: Setup | None = None,
                  freeze_gc: bool = False) -> None:
        """Start, run until :meth:`request_stop` (or SIGINT/SIGTERM if installed), then stop.

        ``setup(node)`` (optionally async) is called once the node is listening. ``freeze_gc``:
        once started, move every object alive to the garbage collector's permanent generation,
        so full collections stop walking the (large) heap of imports and setup, a pause of
        tens of milliseconds otherwise.
        """
        self._bind_loop()
        loop = asyncio.get_running_loop()
        installed: list[signal.Signals] = []
        if install_signal_handlers:  # before start, so a signal right after "listening on" is handled
            for sig in (signal.SIGINT, signal.SIGTERM):
                try:
                    loop.add_signal_handler(sig, self.request_stop)
                    installed.append(sig)
                except (NotImplementedError, RuntimeError, ValueError):
                    pass
        try:
            if self._stop_early:  # stopped before it ran (a signal while the node was being made): never listens
                return
            await self.start()
            if setup is not None:
                result = setup(self)
                if inspect.isawaitable(result):
                    await result
            if freeze_gc:
                gc.collect()
                gc.freeze()
            await self.wait_stop_requested()
            log.info("%s node %s stopping", self.role, self.node_id)
        finally:
            try:  # a second Ctrl-C while stopping must not kill the node before the core has closed
                await self.stop()
            finally:
                for sig in installed:
                    loop.remove_signal_handler(sig)

    # ------------------------------------------------------------ stepping and routing

    def follow_core_rate(self) -> None:
        """Take up a change of ``core.rate_hz`` (a core reconfigured while running): the loop's period from its
        next tick on, no steps at 0 Hz, steps again above; Health's target rate.

        The node looks after each step and each message handled. A rate given to the node (``--rate-hz``)
        stays. A value that is no rate (negative, not a finite number) is refused with a log line and the
        node keeps its rate.
        """
        raw = getattr(self.core, "rate_hz", None)
        seen = self._core_rate_seen
        if raw is seen or _same_number(raw, seen) or self.settings.rate_hz is not None:
            return
        self._core_rate_seen = raw
        try:
            rate = float(cast(float, raw))
        except (TypeError, ValueError):
            rate = math.nan
        if not (math.isfinite(rate) and rate >= 0):
            log.warning("%s core asks for rate_hz %r: not a rate (0 or more Hz); keeping %g Hz", self.role, raw,
                        self.rate_hz)
            return
        if rate != self.rate_hz:
            self._set_rate(rate)

    def _set_rate(self, rate_hz: float) -> None:
        log.info("%s core rate %g Hz -> %g Hz", self.role, self.rate_hz, rate_hz)
        self.rate_hz = rate_hz
        if self.endpoint is None or self.endpoint.closed:  # not started (start takes the rate) or stopped
            return
        if rate_hz == 0:
            if self.loop is not None:
                self.loop.stop()
            return
        if self.loop is not None:
            self.loop.set_rate(rate_hz, int(rate_hz * self.max_catch_up_s))
        self._start_loop()

    def _start_loop(self) -> None:
        """Step the core at ``rate_hz`` unless the loop already runs (or the rate is 0: event-driven)."""
        if not self.rate_hz > 0 or (self._loop_task is not None and not self._loop_task.done()):
            return
        if self.loop is None:
            self.loop = RateLoop(self.rate_hz, self._step, max_catch_up=int(self.rate_hz * self.max_catch_up_s))
        self._tasks = [t for t in self._tasks if not t.done()]  # an earlier run of the loop, ended at 0 Hz
        self._loop_task = self.spawn(self.loop.run(), "rate loop")

    def start_core(self, reason: str = "") -> None:
        """Let the core run: hand it the messages held while waiting for the clock."""
        if self.core_started:
            return
        self.core_started = True
        if reason:
            log.info("%s core starts (%s); %d messages were held", self.role, reason, len(self._held))
        while self._held:
            message, source = self._held.popleft()
            try:
                self.route(self.core.handle(message, self.clock.now(), source), reply_to=source)
            except Exception as exc:
                assert self.endpoint is not None
                self.endpoint.stats.record_drop(DropReason.HANDLER_ERROR, f"{type(exc).__name__}: {exc}", source)
        self.follow_core_rate()

    async def _core_start_timer(self) -> None:
        await asyncio.sleep(self.clock_wait_s)
        if self.core_started:
            return
        if self.clock.synced:
            log.warning("rig clock offset known to +/- %.6f s only after %g s (%d samples): starting on it",
                        self.estimator.uncertainty, self.clock_wait_s, len(self.estimator.samples))
            self.start_core("clock offset uncertain")
            return
        master = self.clock_master_peer()
        if master is None:
            await self._start_without_master()
            return
        # a master to ping that does not answer yet: still starting, as physics is for seconds in a rig
        where = format_address(*master.address)
        log.info("clock master %s at %s has not answered within %g s (still starting?): starting on this node's "
                 "own clock, which follows the master's once it answers", self.settings.clock_master, where,
                 self.clock_wait_s)
        self.start_core("clock master still starting")
        await self._warn_if_still_unsynced(master)

    async def _start_without_master(self) -> None:
        """:meth:`_core_start_timer` when no clock master is known after ``clock_wait_s``: start on this node's own
        clock. Discovery (no ``--peer`` for its role, as ``batteur rig --no-static-peers``) finds a master only once
        it registers, seconds after its start for physics (it builds its scene first): said at INFO, warned about
        only after :data:`MASTER_SILENT_WARN_S`. Without discovery, and no ``--peer`` for the master's role, it is
        never found (a Hello from it makes no peer): warned about at once, saying why."""
        master = self.settings.clock_master
        if self.discovery is None:
            log.warning("no clock master (%s) within %g s, and no way to find one: discovery is off and no --peer "
                        "names a %s node: starting on this node's own clock for good", master, self.clock_wait_s,
                        master)
            self.start_core("clock master not found")
            return
        log.info("clock master (%s) not found by discovery within %g s (still starting?): starting on this node's own "
                 "clock, which follows the master's once it is found", master, self.clock_wait_s)
        self.start_core("clock master not found yet")
        await self._warn_if_still_unsynced(None)

    async def _warn_if_still_unsynced(self, master: Peer | None) -> None:
        """Once :data:`MASTER_SILENT_WARN_S` have passed since the start (the core already runs on this node's own
        clock), warn if the clock is still not synced: the master silent (``master``: the one pinged when the core
        started; None: the one discovery has found by then) or, by discovery, not found at all."""
        await asyncio.sleep(max(0.0, MASTER_SILENT_WARN_S - self.clock_wait_s))
        if self.clock.synced:
            return
        role = self.settings.clock_master
        waited = max(MASTER_SILENT_WARN_S, self.clock_wait_s)
        found = master if master is not None else self.clock_master_peer()
        if found is None:
            log.warning("no clock master (%s) found by discovery within %g s (is it running, on an interface this "
                        "node browses?): rig time is this node's own clock and will jump when the master appears",
                        role, waited)
        else:
            log.warning("no answer from the clock master %s at %s within %g s (is it running?): rig time is this "
                        "node's own clock until it answers", role, format_address(*found.address), waited)

    def _step(self) -> None:
        if not self.core_started:
            return
        try:
            outgoing = self.core.step(self.clock.now())
        except Exception as exc:
            self.step_errors += 1
            self._log_failure("core step", exc)
            outgoing = []
        self.route(outgoing)
        self.follow_core_rate()

    def route(self, outgoing: Sequence[Outgoing], reply_to: str = "") -> None:
        """Send a core's messages: to a role, ``host:port``, or ``"reply"`` (``reply_to``)."""
        assert self.endpoint is not None
        for out in outgoing:
            to = reply_to if out.to == "reply" else out.to
            if not to:
                self.endpoint.unroutable += 1
                continue
            try:
                self.endpoint.send(out.message, to)
            except (OverflowError, struct.error, ValueError, UnicodeError) as exc:
                # a message OSC cannot carry (a float beyond 32 bits, say): not sent, counted; the others go on
                self.endpoint.send_errors += 1
                self._log_error("cannot send %s: %s: %s", out.message.ADDRESS, type(exc).__name__, exc)

    def _on_message(self, message: OscMessage, source: str) -> None:
        endpoint = self.endpoint
        assert endpoint is not None
        if isinstance(message, ClockPing):
            if not self.clock.synced:  # no rig time to give yet: an answer would sync the asker to a wrong clock
                endpoint.stats.record_drop(DropReason.NOT_ALLOWED, "clock ping before this node's clock is synced",
                                           source)
                return
            t = self.clock.now()
            if not self._pong_within_budget(source):
                return
            endpoint.send(answer_ping(message, t, self.clock.now(), self.clock.launch), source)
            return
        if isinstance(message, ClockPong):
            self._on_pong(message, source)
            return
        if isinstance(message, Subscribe):
            self._on_subscribe(message, source)
            return
        if isinstance(message, Hello):
            if not self._hello_within_budget(source):  # not handed to the core either: physics answers its Skeleton
                return
            endpoint.send(self.health(), source)
            if message.role == TOOL_ROLE:  # batteur ls: how its clock follows the master (peers: 1 Hz)
                endpoint.send(self.clock_answer(), source)
        elif isinstance(message, Health):
            if self.silent_peers:
                self._note_peer_back(message, source)
            self.peer_health[message.node_id] = (message, source, time.monotonic())
        owner = taken_elsewhere(type(message), self._service)
        if owner:  # its core would ignore it: counted, said (rated, per reason) and answered, so the sender finds out
            why = (f"{message.ADDRESS} is a control of {owner}: this {self._service} node does not take it (send it "
                   f"to a {owner} node)")
            endpoint.stats.record_drop(DropReason.WRONG_NODE, why, source)
            self._refuse_wrong_node(message, why, source)
            return
        if not self.core_started:
            self._held.append((message, source))
            return
        try:  # an exception here is counted by the endpoint as a handler error
            self.route(self.core.handle(message, self.clock.now(), source), reply_to=source)
        finally:
            self.follow_core_rate()

    def _refuse_wrong_node(self, message: OscMessage, why: str, source: str) -> None:
        """Answer a control of another service with this node's own refusal (:func:`wrong_node_refusal`: physics'
        /batteur/physics/rejected naming /batteur/sound/level), within its sender host's budget
        (:data:`WRONG_NODE_REPLY_RATE_HZ`; past it only counted, ``wrong_node_unanswered``): ``batteur send --to
        HOST:PORT`` of the wrong node said "no reply" and exited 0. Never a loop: a refusal, or any answer, is no
        control taken elsewhere (:func:`~common.transport.taken_elsewhere`), so no node answers this one."""
        reply = wrong_node_refusal(self._service, message.ADDRESS, why)
        if reply is None or self.endpoint is None:
            return
        try:
            host = parse_address(source)[0]
        except ValueError:
            return  # no address to answer
        if not self._wrong_node_budgets.take(host, time.monotonic()):
            self.wrong_node_unanswered += 1
            return
        self.endpoint.send(reply, source)

    def _hello_within_budget(self, source: str) -> bool:
        """Whether a Hello from ``source`` (``host:port``) is answered: its host within its budget
        (:data:`HELLO_ANSWER_RATE_HZ`, charged); else the Hello is counted as dropped (``rate_limited``)."""
        try:
            host = parse_address(source)[0]
        except ValueError:
            host = source
        if self._hello_budgets.take(host, time.monotonic()):
            return True
        assert self.endpoint is not None
        self.endpoint.stats.record_drop(DropReason.RATE_LIMITED, "Hello not answered: its host is over its budget of "
                                        f"{HELLO_ANSWER_BURST:g} at once, then {HELLO_ANSWER_RATE_HZ:g} a second",
                                        source)
        return False

    def _pong_within_budget(self, source: str) -> bool:
        """Whether a clock ping from ``source`` (``host:port``) is answered: its address and its host within their
        budgets (:data:`PONG_ADDRESS_RATE_HZ`, :data:`PONG_HOST_RATE_HZ`, charged); else the ping is counted as
        dropped (``rate_limited``)."""
        try:
            host = parse_address(source)[0]
        except ValueError:
            host = source
        if self._pong_budget.take(host, source, time.monotonic()):
            return True
        assert self.endpoint is not None
        self.endpoint.stats.record_drop(DropReason.RATE_LIMITED, "clock ping not answered: its sender is over its "
                                        f"budget of {PONG_ADDRESS_BURST:g} at once, then {PONG_ADDRESS_RATE_HZ:g} a "
                                        f"second (its host: {PONG_HOST_BURST:g}, then {PONG_HOST_RATE_HZ:g} a second)",
                                        source)
        return False

    def _send_copy(self, data: bytes, to: tuple[str, int]) -> None:
        if self.endpoint is not None and not self.endpoint.closed:
            self.endpoint.send_copy(data, to)

    def _tap(self, address: str, packet: Callable[[], bytes], direction: str) -> None:
        """Every message sent or received: copies to subscribers, values and listeners of OSCQuery."""
        if self.subscriptions.active and not (direction == "in" and address == Subscribe.ADDRESS):
            self.subscriptions.offer(address, packet)  # a Subscribe received: offered by _on_subscribe, which knows
        if self.oscquery is not None:
            self.oscquery.observe(address, packet)

    def _on_subscribe(self, message: Subscribe, source: str) -> None:
        try:
            to = parse_address(source)
        except ValueError:
            return
        # copied to the other subscribers only: its sender knows what it sent (echo '/batteur/*' printed its renewals)
        self.subscriptions.offer(Subscribe.ADDRESS, lambda: encode(message), sender=to)
        renewal = self.subscriptions.is_renewal(to, message.pattern, message.duration_s)
        refusal = self.subscriptions.request(to, message.pattern, message.duration_s)
        if not refusal:
            # echo renews every 5 s: the first subscription (or a changed duration) is news, its renewals are not
            log.log(logging.DEBUG if renewal else logging.INFO, "forwarding %s to %s for %g s", message.pattern,
                    source, message.duration_s)
            return
        # the client's mistake, not this node's (counted in Health's dropped_other): a warning, a few at most
        self._refusal_warnings.warn("subscribe", self.subscriptions.clock(), "subscription of %s to %s refused: %s",
                                    source, message.pattern, refusal)
        self._answer_subscriber(to, source, message.pattern, refusal)

    def _on_undecodable(self, raw: RawMessage, error: MessageError, source: str) -> None:
        """A Subscribe its model refused (a duration out of range, a wrong type: counted and logged by the
        endpoint) is answered like any refused Subscribe: ``batteur echo`` says why it gets nothing."""
        if raw.address != Subscribe.ADDRESS:
            return
        try:
            to = parse_address(source)
        except ValueError:
            return
        first = raw.args[0] if raw.args else ""
        pattern = first[:256] if isinstance(first, str) and first.startswith("/") else "/"  # a reply needs a pattern
        self._answer_subscriber(to, source, pattern, error.detail)

    def _answer_subscriber(self, to: tuple[str, int], source: str, pattern: str, reason: str) -> None:
        if self.subscriptions.may_reply(to) and self.endpoint is not None:  # the subscriber learns why it gets nothing
            reply = SubscribeRefused(node_id=self.node_id, pattern=pattern, reason=_clip(reason, 512))
            self.endpoint.send(reply, source)

    def _on_pong(self, pong: ClockPong, source: str) -> None:
        if not self._from_clock_master(source):
            # a host that sees the pings could answer them first, echoing what the estimator checks
            self.foreign_pongs += 1
            assert self.endpoint is not None
            pinged = "no master pinged yet" if self._ping_to is None else \
                f"the master {self._master_id} is at {format_address(*self._ping_to)}"
            self.endpoint.stats.record_drop(DropReason.NOT_ALLOWED, f"clock pong not from the clock master ({pinged})",
                                            source)
            return
        self._last_pong_at = time.monotonic()
        sample = self.estimator.add_pong(pong, self.clock.local_now())
        if sample is not None:
            first = not self.clock.synced
            step = self.clock.set_offset(self.estimator.offset, self._master_id or self.settings.clock_master,
                                         series=self.estimator.restarts)
            if step and self.core_started:
                self._clock_stepped(step)
            if first:
                log.info(
                    "rig clock synced to %s: offset %+.6f s (+/- %.6f s)",
                    self.settings.clock_master,
                    self.clock.offset,
                    self.estimator.uncertainty,
                )
            if not self.core_started and self._clock_good_enough():
                if not first:
                    log.info("rig clock offset %+.6f s (+/- %.6f s) after %d samples", self.clock.offset,
                             self.estimator.uncertainty, len(self.estimator.samples))
                self.start_core()

    def _clock_stepped(self, step_s: float) -> None:
        """Rig time just stepped by ``step_s`` seconds (logged by the clock): tell a core that has
        ``clock_stepped(step_s, now)`` (the sound core re-anchors its sample clock), so it need not guess from
        time going backward."""
        hook = getattr(self.core, "clock_stepped", None)
        if hook is None:
            return
        try:
            self.route(hook(step_s, self.clock.now()))
        except Exception as exc:
            self.step_errors += 1
            self._log_failure("core clock_stepped", exc)

    def _clock_good_enough(self) -> bool:
        """Whether the offset is known well enough to start the core (:data:`START_UNCERTAINTY_S`), or as well as
        the fast pings will know it."""
        return (self.estimator.uncertainty <= START_UNCERTAINTY_S
                or len(self.estimator.samples) >= FAST_PING_SAMPLES)

    def _from_clock_master(self, source: str) -> bool:
        """True if ``source`` (``host:port``) is the address the clock pings are sent to, as resolved for sending."""
        if self._ping_to is None or self.endpoint is None:
            return False
        try:
            host, port = parse_address(source)
            pinged = self.endpoint.destinations(self._ping_to)
        except ValueError:
            return False
        return any(port == p and same_ip(host, ip) for ip, p in pinged)

    def _on_peer_change(self, event: str, peer: Peer) -> None:
        if peer.node_id == self.node_id:
            return
        act = self._forget_peer_health if event == "removed" else self._greet
        if threading.get_ident() != self._loop_thread and self._aio_loop is not None:
            with contextlib.suppress(RuntimeError):  # its loop closed (this node stopped): no one to greet or forget
                self._aio_loop.call_soon_threadsafe(act, peer)
        else:
            act(peer)

    def _forget_peer_health(self, peer: Peer) -> None:
        """A peer discovery dropped (its goodbye, or its records run out): its last Health is forgotten, so one
        that left on purpose, which discovery says, is not also warned of as silent (:meth:`_note_silent_peers`)."""
        self.peer_health.pop(peer.node_id, None)
        self.silent_peers.discard(peer.node_id)

    def _greet(self, peer: Peer) -> None:
        if self.endpoint is None or self.endpoint.closed:
            return
        log.info("peer %s %s at %s", peer.role, peer.node_id, peer.host)
        self.endpoint.send(self.hello(), peer.address)

    # ------------------------------------------------------------ health and clock

    def hello(self) -> Hello:
        assert self.endpoint is not None
        return Hello(role=self.role, node_id=self.node_id, protocol=PROTOCOL_VERSION, osc_port=self.endpoint.port)

    def health(self) -> Health:
        """This node's Health now (rate achieved over the last health interval)."""
        assert self.endpoint is not None
        stats = self.endpoint.stats
        d = stats.dropped
        # valid messages its core, or its subscription table, refused: dropped all the same
        refused = core_count(self.core, "rejected_total") + self.subscriptions.refused
        other = refused + sum(
            d[r]
            for r in (DropReason.OVERSIZE, DropReason.NOT_ALLOWED, DropReason.RATE_LIMITED, DropReason.HANDLER_ERROR)
        )
        return Health(
            node_id=self.node_id,
            role=self.role,
            protocol=PROTOCOL_VERSION,
            time=self.clock.now(),
            rate_hz=max(0.0, self._achieved_rate),
            target_rate_hz=self.rate_hz,
            overruns=self.loop.overruns if self.loop is not None else 0,
            messages_in=stats.messages_in,
            messages_out=stats.messages_out,
            dropped=stats.dropped_total + refused,
            dropped_malformed=d[DropReason.MALFORMED],
            dropped_unknown=d[DropReason.UNKNOWN_ADDRESS],
            dropped_type=d[DropReason.WRONG_ARITY] + d[DropReason.WRONG_TYPE],
            dropped_range=d[DropReason.OUT_OF_RANGE],
            dropped_other=other,
            late=core_count(self.core, "late"),
            peers=len(self.peers),
            decode_unanswered=self.endpoint.decode_unanswered,
            replies_unanswered=core_count(self.core, "replies_unanswered"),
            target_lag=core_seconds(self.core, "target_lag"),  # physics only: a live drummer playing late
            target_jumps=core_count(self.core, "target_jumps"),
            unroutable=self.endpoint.unroutable,
            dropped_wrong_node=d[DropReason.WRONG_NODE],
            errors=self.step_errors + core_count(self.core, "core_errors"),
            duplicates=core_count(self.core, "duplicates"),
            wrong_node_unanswered=self.wrong_node_unanswered,
            skipped_steps=core_count(self.core, "skipped_steps"),  # physics only: steps it could not simulate in time
            discovery=self.discovery_state,
        )

    async def _health_task(self) -> None:
        while True:
            await asyncio.sleep(self.health_interval_s)
            assert self.endpoint is not None
            self.follow_core_rate()  # a core that changed its rate outside step and handle
            self._achieved_rate = self.loop.achieved_rate() if self.loop is not None else 0.0
            health = self.health()
            status = None if self.is_clock_master else self.clock_status()
            sent: set[tuple[str, int]] = set()
            for peer in self.peers.all():
                if peer.node_id != self.node_id and peer.address not in sent:
                    sent.add(peer.address)
                    self.endpoint.send(health, peer.address)
                    if status is not None:
                        self.endpoint.send(status, peer.address)
            self._note_silent_peers(time.monotonic())

    def _note_peer_back(self, health: Health, source: str) -> None:
        """Say, once, that a peer said to have stopped answering is back, at its next Health (from ``source``): by
        its node id, or by its address and role when restarted by its own command under another id (a node's
        default id holds its pid), whose silent one is then forgotten."""
        for node_id in sorted(self.silent_peers):
            if (last := self.peer_health.get(node_id)) is None:
                continue
            old, old_source, _ = last
            if node_id == health.node_id:
                log.info("peer %s %s at %s answers again", health.role, node_id, source)
            elif old_source == source and old.role == health.role:
                log.info("peer %s %s at %s answers again, restarted as %s", health.role, node_id, source,
                         health.node_id)
                del self.peer_health[node_id]
            else:
                continue
            self.silent_peers.discard(node_id)

    def _note_silent_peers(self, now: float) -> None:
        """Say, once, of each peer whose Health stopped coming :data:`PEER_SILENT_HEALTHS` intervals ago (``now``:
        ``time.monotonic()``) that it stopped answering; its next Health says it is back (:meth:`_note_peer_back`)."""
        limit_s = PEER_SILENT_HEALTHS * self.health_interval_s
        for node_id, (health, source, seen) in self.peer_health.items():
            if node_id not in self.silent_peers and now - seen > limit_s:
                self.silent_peers.add(node_id)
                log.warning("peer %s %s at %s stopped answering: no Health for %.0f s (stopped, or restarting?); "
                            "what is sent to it is lost until it is back", health.role, node_id, source, now - seen)

    def clock_status(self) -> ClockStatus:
        """How this node's clock follows its master now: the estimator's figures and counters, and the steps of rig
        time the clock logged (master restarts)."""
        est = self.estimator
        return ClockStatus(
            node_id=self.node_id,
            synced=int(self.clock.synced),
            offset_s=self.clock.offset,
            uncertainty_s=_or_minus_one(est.uncertainty),
            round_trip_s=_or_minus_one(est.round_trip),
            samples=len(est.samples),
            rejected=est.rejected,
            outliers=est.outliers,
            steps=self.clock.steps,
            foreign_pongs=self.foreign_pongs,
            master=self._master_id,
        )

    def clock_answer(self) -> ClockStatus:
        """The ClockStatus a tool's Hello is answered with beside the Health: :meth:`clock_status`, or for the clock
        master its own node id as ``master`` (its clock is the rig clock: synced, offset and uncertainty 0)."""
        if not self.is_clock_master:
            return self.clock_status()
        return ClockStatus(node_id=self.node_id, synced=1, offset_s=0.0, uncertainty_s=0.0, round_trip_s=-1.0,
                           samples=0, rejected=0, outliers=0, steps=0, foreign_pongs=0, master=self.node_id)

    def clock_master_peer(self) -> Peer | None:
        """The clock master to ping: the one in use while it is known, else the lowest node id of the master role
        (every node picks the same one when there are two, e.g. a restarted master's lingering record, and a
        record flapping does not switch masters). Two known at once are warned about (:meth:`_warn_two_masters`)."""
        masters = self.peers.for_role(self.settings.clock_master)
        current = next((p for p in masters if p.node_id == self._master_id), None)
        chosen = current or min(masters, key=lambda p: p.node_id, default=None)
        if chosen is not None and len(masters) > 1:
            self._warn_two_masters(chosen, masters)
        return chosen

    def _warn_two_masters(self, chosen: Peer, masters: Sequence[Peer]) -> None:
        """Say once per set of them that this node knows several clock masters (two rigs on one network, each with
        its physics: until 8 Dec their sound nodes switched between the two, the rig clock jumping by minutes), which
        one it follows (``chosen``: the one it synced to, kept while it is a peer) and what to do."""
        key = frozenset(p.node_id for p in masters)
        if key in self._masters_warned:
            return
        self._masters_warned.add(key)
        others = ", ".join(f"{p.node_id} at {format_address(*p.address)}" for p in masters if p is not chosen)
        role = self.settings.clock_master
        log.warning("%d clock masters (%s nodes) on the network: %s at %s and %s. This node follows %s and keeps it "
                    "while it answers. Two rigs on one network? Give each its own --rig NAME (or BATTEUR_RIG) on every "
                    "node, or static peers (--peer %s=HOST:PORT); see docs/deployment.md", len(masters), role,
                    chosen.node_id, format_address(*chosen.address), others, chosen.node_id, role)

    def still_answers(self, peer: Peer) -> bool:
        """Whether ``peer`` answered over unicast lately (its Health, or its clock pongs if it is this node's clock
        master, within :data:`PEER_SILENT_HEALTHS` health intervals): discovery keeps such a peer when its mDNS
        records expire unanswered (a firewall dropping multicast), instead of dropping a node that still runs."""
        last = self.peer_health.get(peer.node_id)
        heard = last[2] if last is not None else -math.inf
        if peer.node_id == self._master_id:
            heard = max(heard, self._last_pong_at)
        return time.monotonic() - heard <= PEER_SILENT_HEALTHS * self.health_interval_s

    async def _clock_task(self) -> None:
        """Ping the clock master: quickly until a few samples are in, then every ``ping_interval_s``."""
        while True:
            assert self.endpoint is not None
            master = self.clock_master_peer()
            if master is not None:
                if master.node_id != self._master_id:  # a new (or restarted) master: its answers to old pings are
                    self._master_id = master.node_id   # stale, start over
                    self.estimator.reset()
                ping = self.estimator.make_ping(self.clock.local_now())
                self._ping_to = master.address
                self.endpoint.send(ping, master.address)
            fast = len(self.estimator.samples) < FAST_PING_SAMPLES
            await asyncio.sleep(min(0.1, self.ping_interval_s) if fast else self.ping_interval_s)

    def _log_failure(self, what: str, exc: Exception) -> None:
        """Log a failure of the core (counted in Health's ``errors``): the first of each kind (where, exception
        type) with its traceback, at once; the rest at most once per 5 s, without."""
        kind = (what, type(exc).__name__)
        if kind not in self._failures_logged and len(self._failures_logged) < 64:
            self._failures_logged.add(kind)
            self._last_error_log = time.monotonic()  # the next ones rate-limited from this one
            log.error("%s failed: %s: %s (counted in Health's errors; later ones logged at most every 5 s)",
                      what, type(exc).__name__, exc, exc_info=exc)
            return
        self._log_error("%s failed: %s: %s (%d errors so far)", what, type(exc).__name__, exc, self.step_errors)

    def _log_error(self, text: str, *args: object) -> None:
        now = time.monotonic()
        if now - self._last_error_log >= 5.0:
            self._last_error_log = now
            log.error(text, *args)


# --------------------------------------------------------------------------- command line

def stopped_while_starting(role: str, signal_name: str) -> str:
    """What a node logs when a stop came while it was starting (:class:`StoppedWhileStarting`, ``signal_name``: the
    signal's): it was asked to stop and did, cleanly; "physics stopped while starting (SIGTERM)" read like a crash
    after the user's Ctrl-C on ``batteur rig``, which stops its services with SIGTERM (a node cannot tell who sent
    it: the rig on Ctrl-C, its --duration's end or another service's exit, or a service manager)."""
    why = "Ctrl-C" if signal_name == "SIGINT" else "a stop request, e.g. batteur rig's on Ctrl-C"
    # "stopping", not "stopped": the process has yet to exit (a loaded machine's physics, killed at the rig's stop
    # timeout after this line, read as a contradiction)
    return f"{role} was asked to stop while starting ({signal_name}: {why}): stopping cleanly before it listened"


class StoppedWhileStarting(BaseException):
    """Raised in the main thread by SIGINT or SIGTERM while :func:`run_node`'s ``make_core`` runs: it unwinds the
    core's making, whose code closes what it had started (``except BaseException``, as for Ctrl-C), and the node
    exits 0 at once. A BaseException, so that ``except Exception`` does not swallow it."""


class _StartSignals:
    """SIGINT/SIGTERM from when the core starts being made until the node's event loop takes them over.

    The default action killed the process: nothing closed what the core had started (physics: its planning
    processes, whose named semaphores the resource tracker then unlinked with a "leaked semaphore" warning).
    Waiting for ``make_core`` to end would not do: physics takes 3-6 s to make on a loaded machine, past the
    rig's stop timeout (4 s). So the first signal raises :class:`StoppedWhileStarting` inside ``make_core``; once
    raised, or once the core is made (:meth:`forward_to`), a signal only asks the node to stop (an exception there
    would skip ``core.close``).
    """

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self) -> None:
        self.received = False
        self._stop: Callable[[], None] | None = None
        self._raise = True
        self._previous: dict[signal.Signals, Any] = {}

    def install(self) -> None:
        """Catch SIGINT and SIGTERM (in the main thread; elsewhere they stay as they are)."""
        for sig in self.SIGNALS:
            try:
                self._previous[sig] = signal.signal(sig, self._on_signal)
            except ValueError:  # not the main thread: signals stay as they were
                pass

    def _on_signal(self, signum: int, frame: object) -> None:
        self.received = True
        if self._stop is not None:
            self._stop()
        elif self._raise:
            self._raise = False  # once: a second signal must not cut the clean-up the first one started
            raise StoppedWhileStarting(signal.Signals(signum).name)

    def forward_to(self, stop: Callable[[], None]) -> None:
        """The core is made: from now on a signal calls ``stop`` (at once if one came already)."""
        self._raise = False
        self._stop = stop
        if self.received:
            stop()

    def restore(self) -> None:
        """Put back the handlers there were before."""
        self._raise = False
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)
        self._previous.clear()


def _close_core(core: Core) -> None:
    """``core.close()`` if it has one (a failure logged)."""
    close = getattr(core, "close", None)
    if callable(close):
        try:
            close()
        except Exception as exc:
            log.warning("core close failed: %s", exc)


MakeCore = Callable[[NodeSettings, argparse.Namespace], Core]
AddArguments = Callable[[argparse.ArgumentParser], object]
_METAVARS = {"peers": "ROLE=HOST:PORT", "interfaces": "ADDRESS", "allow": "NETWORK", "absent": "ROLE"}


def build_parser(
    role: str,
    description: str = "",
    add_arguments: AddArguments | None = None,
    settings_cls: type[NodeSettings] = NodeSettings,
) -> argparse.ArgumentParser:
    """An argparse parser with a flag for every setting (plus ``--config``) and the service's own; a value that
    starts with '-' and is a number (``--epoch -1e3``) is read as one, for the setting's own check to judge."""
    parser = take_negative_values(argparse.ArgumentParser(
        prog=f"batteur {role}",
        description=description or f"Run the {role} service node.",
        epilog=(
            "Every setting can also come from the environment (BATTEUR_<NAME>, e.g. BATTEUR_PORT=9000, "
            "BATTEUR_PEERS=sound=10.0.0.5:9000,graphics=10.0.0.6:9100) or a YAML/TOML file (--config, "
            "or BATTEUR_CONFIG). Precedence: flags > environment > file > defaults. See docs/runtime.md."
        ),
    ))
    group = parser.add_argument_group("node settings")
    group.add_argument("--config", metavar="FILE", default=argparse.SUPPRESS,
                       help="YAML or TOML file of settings (keys: the setting names below, with underscores)")
    for name, field in settings_cls.model_fields.items():
        flag = flag_name(name)
        env = f"{ENV_PREFIX}{name.upper()}"
        text = (field.description or name).replace("%", "%%")
        annotation = field.annotation
        if annotation is bool:
            default = "on" if field.default else "off"
            group.add_argument(flag, dest=name, action=argparse.BooleanOptionalAction, default=argparse.SUPPRESS,
                               help=f"{text} (default {default}; env {env})")
        elif getattr(annotation, "__origin__", None) is list:
            group.add_argument(flag, dest=name, action="append", metavar=_METAVARS.get(name, name.upper()),
                               default=argparse.SUPPRESS, help=f"{text}; repeatable (env {env}, comma-separated)")
        else:
            has_default = field.default_factory is None and field.default not in (None, "")
            shown = f"default {field.default}; " if has_default else ""
            if name == "role":
                shown = f"default {role}; "
            group.add_argument(flag, dest=name, metavar=name.upper(), default=argparse.SUPPRESS,
                               help=f"{text} ({shown}env {env})")
    group.add_argument("--show-settings", action="store_true",
                       help="print the settings in effect as JSON and exit")
    if add_arguments is not None:
        add_arguments(parser)
    return parser


def run_node(
    role: str,
    make_core: MakeCore,
    argv: Sequence[str] | None = None,
    add_arguments: AddArguments | None = None,
    description: str = "",
    *,
    settings_cls: type[NodeSettings] = NodeSettings,
    setup: Setup | None = None,
    discovery_factory: DiscoveryFactory | None = None,
) -> int:
    """Parse the command line, load the settings, build the core and run it as a node until SIGINT/SIGTERM.

    Parameters
    ----------
    role : str
        The service's role (the default of ``--role``).
    make_core : callable(settings, args) -> Core
        Builds the core. ``args`` holds the options added by ``add_arguments``.
        Raise ValueError (or SettingsError) for a bad option: it is printed, exit code 2.
    argv : sequence of str
        Command-line arguments (default ``sys.argv[1:]``).
    add_arguments : callable(parser)
        Adds the service's own options to the argparse parser (their values reach ``make_core``).
    description : str
        The ``--help`` text.
    settings_cls : type
        A subclass of NodeSettings with the service's own settings (each gets a flag and an env var).
    setup : callable(node), optionally async
        Called once the node is listening, e.g. to ``node.spawn()`` a web server.

    Returns
    -------
    int
        The exit status (common/exit_status.py): 0 after a clean stop; 2 for a setting or option refused; 1 for
        a file it cannot use (the config file, or ``make_core`` raising OSError or InputError), a port it cannot
        bind or a node that failed.
    """
    parser = build_parser(role, description, add_arguments, settings_cls)
    args = parser.parse_args(argv)
    fields = set(settings_cls.model_fields)
    given = {k: v for k, v in vars(args).items() if k in fields}
    extra = argparse.Namespace(**{k: v for k, v in vars(args).items() if k not in fields and k != "config"})
    try:
        settings = load_settings(given, getattr(args, "config", None), {"role": role}, settings_cls)
    except ConfigFileError as exc:  # a file it cannot use (1), told apart from the values it holds (2)
        return report_error(parser.prog, exc, FAILED)
    except SettingsError as exc:
        return report_error(parser.prog, str(exc), USAGE)
    if settings.discovery:
        problem = check_interfaces(settings.interfaces)
        if problem:
            return report_error(parser.prog, f"invalid setting interfaces: {problem} "
                                "[--interface / BATTEUR_INTERFACES]", USAGE)
    if args.show_settings:
        print(json.dumps(settings.model_dump(mode="json"), indent=2))
        return 0
    logging.basicConfig(
        level=settings.log_level, format="%(asctime)s %(levelname)s %(name)s: %(message)s", stream=sys.stderr
    )
    signals = _StartSignals()
    try:
        signals.install()
        return _make_and_run(parser.prog, make_core, settings, extra, signals, setup, discovery_factory)
    except StoppedWhileStarting as stop:  # before make_core began
        log.info("%s", stopped_while_starting(role, str(stop)))
        return 0
    finally:
        signals.restore()


def _make_and_run(prog: str, make_core: MakeCore, settings: NodeSettings, extra: argparse.Namespace,
                  signals: _StartSignals, setup: Setup | None, discovery_factory: DiscoveryFactory | None) -> int:
    """:func:`run_node` once the settings are loaded: make the core, run it as a node; the exit status. ``prog``
    (``batteur ROLE``) starts the error lines."""
    core: Core | None = None
    try:
        try:
            core = make_core(settings, extra)
        except (InputError, OSError) as exc:  # a file it cannot use: not the command line's fault
            return report_error(prog, str(exc), FAILED)
        except (ValueError, SettingsError) as exc:
            return report_error(prog, str(exc), USAGE)
        try:
            node = Node(core, settings, discovery_factory=discovery_factory)
        except ValueError as exc:  # the settings refused by the node: what the core started is closed
            _close_core(core)
            return report_error(prog, str(exc), USAGE)
        signals.forward_to(node.request_stop)
    except StoppedWhileStarting as stop:
        if core is not None:  # made already: the node was not
            _close_core(core)
        log.info("%s", stopped_while_starting(settings.role, str(stop)))
        return 0
    try:
        asyncio.run(node.run(install_signal_handlers=True, setup=setup, freeze_gc=True))
    except OSError as exc:
        where = f"{settings.host}:{settings.port}" if settings.port else settings.host
        return report_error(prog, f"cannot run the node on {where}: {exc.strerror or exc}", FAILED)
    except KeyboardInterrupt:
        return 0
    return 1 if node.failed else 0
