"""UDP transport for typed OSC messages, with its own asyncio receive loop.

:class:`UdpEndpoint` has the interface of :class:`common.bus.MemoryEndpoint`
(``send(message, to)``, ``set_handler(fn(message, source))``, ``.stats``), so a
node can run on either. python-osc only builds packets, and
:mod:`common.messages.codec` parses them; the socket and the receive loop are ours, because
python-osc's own servers block on bundles timetagged in the future and drop
datagrams over 8 KiB. Bundle timetags are ignored (timed messages carry their
rig time as an argument).

Every received datagram goes through, in order: the allow-list (source
networks), the size limit, the per-source rate limit, parsing, the message
model, the handler. A failure at any stage drops what failed (one datagram,
or one message of a bundle), counts it in ``stats`` under its
:class:`~common.messages.DropReason` and logs it at most once per reason per
interval; the loop carries on. A control message of a known address that the
model refuses (wrong argument count or type, a value out of range) is also
answered to its sender with its service's refusal (:func:`decode_refusal`),
within a reply budget per sender host, by the node of that service only (an
endpoint opened with ``role``: a sound node counts and drops a malformed
physics control, unanswered); streams (contacts, poses, impacts ...) never are.

Addresses: a destination ``to`` is a role (every peer of that role in the
:class:`~common.peers.PeerTable`), ``"host:port"`` (IPv6 as ``"[::1]:9000"``)
or a ``(host, port)`` tuple. Sources are reported as ``"host:port"`` in the
same form.
"""

from __future__ import annotations

import asyncio
import functools
import ipaddress
import logging
import socket
import sys
import time
from collections.abc import Callable, Iterable, Sequence
from typing import Any

from pydantic import ValidationError

from common.messages import REGISTRY, Arg, DropReason, Family, MessageError, MessageRegistry, OscMessage
from common.messages.codec import (
    RawMessage,
    encode,
    encode_bundle,
    encode_raw,
    parse_packet,
    to_model,
    walk_packet,
)
from common.messages.graphics import GraphicsRejected
from common.messages.interaction import InteractionError, ListEnd, MapInfo, MessageInfo
from common.messages.physics import PhysicsRejected
from common.messages.sound import SoundRejected
from common.peers import PeerTable
from common.rated_log import RatedWarnings
from common.stats import TrafficStats
from common.token_bucket import TokenBuckets

log = logging.getLogger("batteur.transport")

Handler = Callable[[OscMessage, str], None]
"""Receives (message, source) with source ``"host:port"``."""
RawHandler = Callable[[RawMessage, str], None]
"""Receives (raw message, source) for addresses that have no model but a raw route."""
Tap = Callable[[str, Callable[[], bytes], str], None]
"""Sees every message sent or received: (address, packet of that one message (lazy), "in" | "out")."""
Target = str | tuple[str, int]
IpNetwork = ipaddress.IPv4Network | ipaddress.IPv6Network
IpAddress = ipaddress.IPv4Address | ipaddress.IPv6Address

MAX_UDP_PAYLOAD = 65507
"""Largest UDP payload over IPv4, bytes."""
DEFAULT_RCVBUF = 16 * 1024 * 1024
"""Receive buffer requested by default, bytes (a 10,000-message burst on loopback fits)."""
NAME_TTL_S = 30.0
"""A host name's address is looked up again (in the background) after this long, seconds."""
NAME_RETRY_S = 5.0
"""A host name that did not resolve is tried again after this long, seconds."""
MAX_WAITING = 64
"""Packets held per host name while its first lookup runs; more are not sent (``unroutable``)."""
DRAIN_DATAGRAMS = 256
"""Datagrams read from the socket at most after each one asyncio hands over (see ``UdpEndpoint._drain``)."""
MAX_READ_BYTES = 65536
"""Receive size: any UDP datagram (longer than ``max_datagram`` is dropped as oversize, as asyncio's read)."""
DECODE_REPLY_RATE_HZ = 5.0
"""Undecodable control messages answered per second to one sender host (past it, and the burst, they are only
counted: ``decode_unanswered``), so forged packets cannot turn a node into a reflector."""
DECODE_REPLY_BURST = 10.0
"""Undecodable control messages answered to one sender host at once before :data:`DECODE_REPLY_RATE_HZ`."""
DECODE_REPLY_REASONS = frozenset({DropReason.WRONG_ARITY, DropReason.WRONG_TYPE, DropReason.OUT_OF_RANGE})
"""Decoding failures answered: the address is known, its arguments are not what its model takes."""
NO_PEER_LOG_INTERVAL_S = 60.0
"""Sends to a role with no known peer are warned about at most once per this long per role, seconds (the first
time with what to do; the others counted in the next line and in Health's ``unroutable``)."""
NO_PEER_GRACE_S = 10.0
"""Sends to a role with no known peer in the first this long after the endpoint opened are only counted, seconds:
discovery finds the other nodes of a rig started together within a few seconds (no warning at every start)."""
REFUSAL_ENDINGS = ("/error", "/rejected", "/refused")
"""Addresses of refusals (as ``batteur send --replies`` knows them): a malformed one is never answered, so two
peers cannot answer each other's refusals without end."""


SERVICE_OF = {"score": "physics"}
"""The role whose node owns an address family (/batteur/FAMILY/...) when it is not the family's name: the physics
node plays scores."""


def owner_role(address: str) -> str:
    """The role of the node that owns ``address`` (``/batteur/score/tempo``: physics); "" outside /batteur/."""
    family = address.split("/")[2] if address.startswith("/batteur/") else ""
    return SERVICE_OF.get(family, family)


SERVICE_ROLES = ("physics", "interaction", "sound", "graphics")
"""The services' roles: a node of one takes only its own service's controls (:func:`taken_elsewhere`)."""
ANSWERS: tuple[type[OscMessage], ...] = (ListEnd, MapInfo, MessageInfo)
"""Controls a service sends back to whoever asked (interaction's listings), as its refusals (addresses ending as
``REFUSAL_ENDINGS``): answers to a request, never a control for the node they reach to take."""


def taken_elsewhere(model: type[OscMessage], role: str) -> str:
    """The service role whose node takes messages of ``model``, when a node whose core plays the service ``role``
    does not ("" when it does, or ignores them on purpose): what the runtime drops as ``wrong_node`` and
    ``batteur send --to ROLE`` refuses.

    A service's node takes only its own service's controls (``/batteur/score/...``: physics); each core ignores the
    others' (a live note sent to interaction). Not one of them: the streams and system messages (impacts, dampings,
    poses, contacts, Health, Hello, clock: broadcast to every peer, forwarded to graphics, copied by routes; each
    core takes what it needs of them), the answers a service sends back (refusals, interaction's listings: what
    the node asked for), a control of no service node (the recogniser's hits), and any message to a core of no
    service's role (a test's, a wrapper's: its handlers are its own)."""
    if role not in SERVICE_ROLES or model.FAMILY is not Family.CONTROL:
        return ""
    owner = owner_role(model.ADDRESS)
    if owner == role or owner not in SERVICE_ROLES:
        return ""
    if model.ADDRESS.endswith(REFUSAL_ENDINGS) or issubclass(model, ANSWERS):
        return ""
    return owner


def decode_refusal(address: str, reason: str, registry: MessageRegistry = REGISTRY,
                   role: str | None = None, args: Sequence[Arg] = ()) -> OscMessage | None:
    """The refusal of the service that owns ``address`` for a control message there that could not be decoded
    (``reason``, clipped to 512 characters): /batteur/physics/... and /batteur/score/... (the physics node plays
    scores) :class:`PhysicsRejected`, /batteur/sound/... :class:`SoundRejected`,
    /batteur/interaction/... :class:`InteractionError`, /batteur/graphics/... :class:`GraphicsRejected`. A sound
    refusal names the instrument when the message's first field is one and its first argument (of ``args``, the
    message's) is a valid one (``tension snare 5``: ``snare``), else ''. None for a
    stream (any family but control), a refusal itself, an unknown address, a service without a refusal message
    (the recogniser), or, given the answering node's ``role``, an address another role owns (:func:`owner_role`):
    a refusal speaks for its service, so only that service's node sends it."""
    model = registry.get(address)
    if model is None or model.FAMILY is not Family.CONTROL or address.endswith(REFUSAL_ENDINGS):
        return None
    service = owner_role(address)
    if role is not None and service != role:
        return None
    instrument = _first_instrument(model, args) if service == "sound" else ""
    return service_refusal(service, address, reason[:512], instrument)


def service_refusal(role: str | None, address: str, reason: str, instrument: str = "") -> OscMessage | None:
    """The refusal the service ``role`` answers a control at ``address`` with (its own message, the one table of
    them: :func:`decode_refusal`, ``common.runtime.wrong_node_refusal``): :class:`PhysicsRejected`,
    :class:`SoundRejected` (naming ``instrument``, '' for none), :class:`InteractionError`,
    :class:`GraphicsRejected`; None for a role with no refusal message. ``reason`` as it is (callers clip it)."""
    if role == "physics":
        return PhysicsRejected(address=address, reason=reason)
    if role == "sound":
        return SoundRejected(address=address, instrument=instrument, reason=reason)
    if role == "interaction":
        return InteractionError(request=address, detail=reason)
    if role == "graphics":
        return GraphicsRejected(address=address, reason=reason)
    return None


def _first_instrument(model: type[OscMessage], args: Sequence[Arg]) -> str:
    """``args[0]`` when ``model``'s first field is ``instrument`` and it is a valid one, else ''."""
    fields = list(model.model_fields)
    if not args or not fields or fields[0] != "instrument" or not isinstance(args[0], str):
        return ""
    try:
        model.__pydantic_validator__.validate_assignment(model.model_construct(), "instrument", args[0])
    except ValidationError:
        return ""
    return args[0]


def format_address(host: str, port: int) -> str:
    """``host:port``, with IPv6 hosts in brackets (``[::1]:9000``)."""
    return f"[{host}]:{port}" if ":" in host else f"{host}:{port}"


def parse_address(text: str) -> tuple[str, int]:
    """Split ``host:port`` or ``[v6host]:port``; raise ValueError if it is not one."""
    if text.startswith("["):
        host, sep, port_text = text[1:].partition("]:")
    else:
        host, sep, port_text = text.rpartition(":")
        if ":" in host:
            raise ValueError(f"{text!r}: put IPv6 hosts in brackets, e.g. [::1]:9000")
    if not sep or not host or not port_text.isdigit():
        raise ValueError(f"{text!r} is not HOST:PORT")
    port = int(port_text)
    if not 0 < port < 65536:
        raise ValueError(f"{text!r}: port out of range 1-65535")
    return host, port


def _unmap(ip: IpAddress) -> IpAddress:
    if isinstance(ip, ipaddress.IPv6Address) and ip.ipv4_mapped is not None:
        return ip.ipv4_mapped
    return ip


def same_ip(a: str, b: str) -> bool:
    """True if two numeric addresses are the same host (an IPv4-mapped IPv6 address is its IPv4 one; a scope
    ``%zone`` is ignored); text that is not an address is compared as it is."""
    try:
        ip_a, ip_b = (ipaddress.ip_address(x.split("%")[0]) for x in (a, b))
    except ValueError:
        return a == b
    return _unmap(ip_a) == _unmap(ip_b)


class _Name:
    """A host name's lookup: its address ("" if it failed), when it was looked up, packets waiting for it."""

    __slots__ = ("address", "stamp", "waiting", "task")

    def __init__(self) -> None:
        self.address: str | None = None
        """None until the first lookup ends."""
        self.stamp = 0.0
        self.waiting: list[tuple[bytes, int, int]] = []
        """(packet, port, message count) sent once the name resolves"""
        self.task: asyncio.Task[None] | None = None


class _Protocol(asyncio.DatagramProtocol):
    def __init__(self, endpoint: UdpEndpoint) -> None:
        self.endpoint = endpoint

    def datagram_received(self, data: bytes, addr: tuple[str | Any, int]) -> None:
        self.endpoint._receive(data, addr)
        self.endpoint._drain()

    def error_received(self, exc: Exception) -> None:
        self.endpoint.send_errors += 1
        self.endpoint._log_limited("socket", logging.WARNING, "socket error: %s", exc)


class UdpEndpoint:
    """An asyncio UDP endpoint sending and receiving typed OSC messages.

    Create with :meth:`open`. Not thread-safe: use it from its event loop.

    Attributes
    ----------
    stats : TrafficStats
        Valid messages in, messages out (one per message per destination
        datagram), drops per reason.
    unroutable : int
        Sends to a role with no known peer (warned about, :meth:`_warn_no_peer`), or
        to an address that cannot be resolved or reached from this socket's address
        family. A node reports it in its Health.
    decode_unanswered : int
        Undecodable control messages not answered: their sender host was over
        its reply budget (:data:`DECODE_REPLY_RATE_HZ`). A node reports it in
        its Health.
    role : str or None
        The node's role: only controls its role owns are answered when
        undecodable (None: any service's, for an endpoint that is no node).
    send_errors : int
        Socket errors while sending, and messages too large to send.
    rcvbuf_bytes : int
        Receive buffer size the kernel granted, bytes.
    """

    def __init__(
        self,
        sock: socket.socket,
        peers: PeerTable,
        registry: MessageRegistry,
        max_datagram: int,
        allow: Sequence[IpNetwork] | None,
        max_rate: float | None,
        max_burst: float | None,
        stats: TrafficStats,
        clock: Callable[[], float],
        role: str | None = None,
    ) -> None:
        self._sock = sock
        self.peers = peers
        self.registry = registry
        self.max_datagram = max_datagram
        self.allow = list(allow) if allow is not None else None
        self.max_rate = max_rate
        self.max_burst = max_burst if max_burst is not None else (max_rate or 0.0)
        self.stats = stats
        self.unroutable = 0
        self.send_errors = 0
        self.rcvbuf_bytes = sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)
        self._clock = clock
        self._family = sock.family
        self._handler: Handler | None = None
        self.tap: Tap | None = None
        """Called for every valid message received and every message sent (``batteur echo``, OSCQuery); a message
        sent to several destinations in one turn of the event loop (Health to each peer) is one call."""
        self._tapped_out: set[bytes] = set()
        """The packets given to the tap since the event loop's last turn (:meth:`_first_send`)."""
        self._raw_routes: list[tuple[str, RawHandler]] = []
        self._transport: asyncio.DatagramTransport | None = None
        self._buckets = TokenBuckets(self.max_rate or 0.0, max(self.max_burst, 1.0))
        """Sender host -> its budget of messages (``max_rate``)."""
        self._reply_budgets = TokenBuckets(DECODE_REPLY_RATE_HZ, DECODE_REPLY_BURST)
        """Sender host -> its budget of answers to undecodable control messages."""
        self.decode_unanswered = 0
        self.role = role
        self.on_undecodable: Callable[[RawMessage, MessageError, str], None] | None = None
        """Called with (raw message, error, source) for each message of a known address its model refused (arity,
        type, range), once counted and answered (:func:`decode_refusal`): a node answers what this endpoint cannot
        (a refused Subscribe, with its node id)."""
        self._names: dict[str, _Name] = {}
        self._loop: asyncio.AbstractEventLoop | None = None
        self._allowed_cache: dict[str, bool] = {}
        self._last_log: dict[str, float] = {}
        self._no_peer_warnings = RatedWarnings(log, NO_PEER_LOG_INTERVAL_S)
        """Sends to a role with no known peer: by role, on ``clock`` (:meth:`_warn_no_peer`)."""
        self._no_peer_told: set[str] = set()
        """Roles whose missing peer was explained in full once."""
        self.absent_roles: set[str] = set()
        """Roles left out on purpose (a node's ``--absent``: a rig started without them): sends to one with no peer
        are counted in ``unroutable``, not warned about (a peer of it found later is still sent to)."""
        self._opened_at = clock()
        host, port = sock.getsockname()[:2]
        self.local_address = format_address(host, port)
        """This endpoint's ``host:port``."""
        self.port: int = port

    # ------------------------------------------------------------------ setup

    @classmethod
    async def open(
        cls,
        host: str = "127.0.0.1",
        port: int = 0,
        peers: PeerTable | None = None,
        registry: MessageRegistry = REGISTRY,
        max_datagram: int = MAX_UDP_PAYLOAD,
        allow: Iterable[IpNetwork | str] | None = None,
        max_rate: float | None = None,
        max_burst: float | None = None,
        rcvbuf_bytes: int = DEFAULT_RCVBUF,
        stats: TrafficStats | None = None,
        clock: Callable[[], float] = time.monotonic,
        role: str | None = None,
    ) -> UdpEndpoint:
        """Bind a UDP socket and start receiving.

        Parameters
        ----------
        host, port : str, int
            Where to listen. Port 0 picks a free port. ``"::"`` listens on IPv6 and IPv4.
        peers : PeerTable
            Where roles are looked up when sending to a role.
        registry : MessageRegistry
            Models for decoding.
        max_datagram : int
            Larger datagrams are dropped (``oversize``) and not sent, bytes.
        allow : list of ip networks or None
            Only these source networks are accepted (``not_allowed``); None: any source.
        max_rate : float or None
            Messages per second accepted from one source IP, a bundle counting each message it holds
            (``rate_limited``: the whole datagram); None: no limit.
        max_burst : float or None
            Messages a source may send at once before the rate applies (default: ``max_rate``).
        rcvbuf_bytes : int
            Receive buffer to ask the kernel for, bytes (root may exceed ``net.core.rmem_max``).
        clock : callable -> float
            Monotonic seconds, for the rate limit.
        role : str or None
            The node's role (physics, sound, ...): an undecodable control is answered only when this role owns
            its address (:func:`decode_refusal`); None answers for any service.
        """
        sock = _bind(host, port, rcvbuf_bytes)
        networks = None if allow is None else [ipaddress.ip_network(n, strict=False) for n in allow]
        endpoint = cls(
            sock,
            peers if peers is not None else PeerTable(),
            registry,
            max_datagram,
            networks,
            max_rate,
            max_burst,
            stats if stats is not None else TrafficStats(),
            clock,
            role,
        )
        loop = asyncio.get_running_loop()
        transport, _ = await loop.create_datagram_endpoint(lambda: _Protocol(endpoint), sock=sock)
        endpoint._transport = transport
        endpoint._loop = loop
        log.info("listening on %s (receive buffer %d bytes)", endpoint.local_address, endpoint.rcvbuf_bytes)
        return endpoint

    def set_handler(self, handler: Handler) -> None:
        """Call ``handler(message, source)`` for every valid message received."""
        self._handler = handler

    def add_raw_route(self, prefix: str, handler: RawHandler) -> None:
        """Deliver messages whose address starts with ``prefix`` and has no model to ``handler``.

        For messages registered at run time (e.g. instrument parameters); their
        arguments are not validated here.
        """
        self._raw_routes.append((prefix, handler))

    def close(self) -> None:
        """Stop receiving and close the socket (pending host name lookups are abandoned)."""
        for name in self._names.values():
            if name.task is not None:
                name.task.cancel()
            self.unroutable += sum(count for _, _, count in name.waiting)
            name.waiting.clear()
        if self._transport is not None:
            self._transport.close()
            self._transport = None
        else:
            self._sock.close()

    @property
    def closed(self) -> bool:
        return self._transport is None

    def connect(self, to: tuple[str, int]) -> None:
        """Connect the socket to the one destination ``to`` (as this socket's family addresses it): sends to it
        still work, and the kernel reports its ICMP errors (port unreachable: nothing listens there) to this socket
        (:meth:`pending_error`), which it does not for an unconnected UDP socket. ``OSError`` if it cannot be."""
        addresses = self.destinations(to)
        if not addresses or self.closed:
            raise OSError(f"cannot connect to {format_address(*to)}: no address of this socket's family")
        self._sock.connect(addresses[0])

    def pending_error(self) -> int:
        """The socket's pending error number (``SO_ERROR``, 0 for none), cleared by reading it: on a connected
        socket, ``errno.ECONNREFUSED`` once a datagram sent was refused."""
        if self.closed:
            return 0
        return int(self._sock.getsockopt(socket.SOL_SOCKET, socket.SO_ERROR))

    # ---------------------------------------------------------------- sending

    def send(self, message: OscMessage, to: Target) -> None:
        """Send one typed message to a role, ``"host:port"`` or ``(host, port)``."""
        data = encode(message)
        self._send_packet(data, to, 1)
        if self.tap is not None:
            self._tap_out(message.ADDRESS, data)

    def send_raw(self, address: str, args: Sequence[Arg], to: Target) -> None:
        """Send one message that has no model (ints as ``i``, floats as ``f``, strings as ``s``)."""
        data = encode_raw(address, args)
        self._send_packet(data, to, 1)
        if self.tap is not None:
            self._tap_out(address, data)

    def send_bundle(self, messages: Sequence[OscMessage], to: Target, timetag: float | None = None) -> None:
        """Send several messages in one bundle (``timetag``: Unix seconds; receivers ignore it)."""
        if messages:
            self._send_packet(encode_bundle(messages, timetag), to, len(messages))
            if self.tap is not None:
                for message in messages:
                    self._tap_out(message.ADDRESS, encode(message))

    def send_copy(self, data: bytes, to: tuple[str, int]) -> None:
        """Send an already encoded packet to one socket address, outside the message counters (copies)."""
        if self._transport is not None and len(data) <= self.max_datagram and _valid_target(*to):
            ip = self._resolve(to[0])
            if ip:
                self._transport.sendto(data, (ip, to[1]))

    def receive_datagram(self, data: bytes, host: str, port: int) -> None:
        """Handle a datagram that arrived another way (e.g. OSC over OSCQuery's WebSocket), with every check."""
        self._receive(data, (host, port))

    def _tap_out(self, address: str, data: bytes) -> None:
        tap = self.tap
        if tap is not None and self._first_send(data):
            try:
                tap(address, lambda: data, "out")
            except Exception as exc:  # a tap must never break sending
                self._log_limited("tap", logging.WARNING, "tap failed: %s: %s", type(exc).__name__, exc)

    def _first_send(self, data: bytes) -> bool:
        """Whether ``data`` is not yet tapped in this turn of the event loop: the same packet again in one turn is
        the same send to another destination (a node sends its Health to each peer in one go; ``batteur echo``
        printed it once per peer). Without a loop, every packet is tapped."""
        if data in self._tapped_out:
            return False
        loop = self._loop
        if loop is None or loop.is_closed():
            return True
        if not self._tapped_out:  # forgotten once the sends of this turn are done
            loop.call_soon(self._tapped_out.clear)
        self._tapped_out.add(data)
        return True

    def destinations(self, to: Target) -> list[tuple[str, int]]:
        """The socket addresses ``to`` means now (empty if none is known or reachable).

        A host name not looked up yet is left out; its lookup starts in the background.
        """
        out: list[tuple[str, int]] = []
        for host, port in self._targets(to):
            ip = self._resolve(host)
            if ip:
                out.append((ip, port))
        return out

    def _targets(self, to: Target) -> list[tuple[str, int]]:
        """(host, port) pairs of a destination, unresolved; raise ValueError for a malformed one."""
        if isinstance(to, tuple):
            if not _valid_target(*to):
                raise ValueError(f"{to!r} is not a (host, port 1-65535) pair")
            return [to]
        if ":" in to or to.startswith("["):
            return [parse_address(to)]
        return [p.address for p in self.peers.for_role(to) if _valid_target(*p.address)]

    def _send_packet(self, data: bytes, to: Target, count: int) -> None:
        if self._transport is None:
            raise RuntimeError("endpoint is closed")
        if len(data) > self.max_datagram:
            self.send_errors += count
            self._log_limited("send-oversize", logging.WARNING, "not sent: %d bytes > max_datagram %d to %s",
                              len(data), self.max_datagram, to)
            return
        try:
            targets = self._targets(to)
        except ValueError as exc:
            self.unroutable += count
            self._log_limited("bad-target", logging.WARNING, "not sent: %s", exc)
            return
        if not targets:
            self.unroutable += count
            self._warn_no_peer(str(to))
            return
        for host, port in targets:
            ip = self._resolve(host)
            if ip:
                self._transport.sendto(data, (ip, port))
                self.stats.messages_out += count
            elif ip is None:
                self._wait_for_name(host, data, port, count)
            else:
                self.unroutable += count

    def _warn_no_peer(self, role: str) -> None:
        """Say that messages to ``role`` are not sent, as no peer of it is known: the first time in full (what to do),
        then at most once per :data:`NO_PEER_LOG_INTERVAL_S` with the count held back, so a role left out of the rig
        on purpose (graphics not started, 60 poses a second) costs a line a minute, not a flood; nothing at all for a
        role in :attr:`absent_roles` (left out on purpose, as the rig says). Nothing is said in the first
        :data:`NO_PEER_GRACE_S` (the peers of a rig starting together are still being found)."""
        if role in self.absent_roles:
            return  # not started on purpose: counted only
        now = self._clock()
        if now - self._opened_at < NO_PEER_GRACE_S:
            return  # the rig's other nodes may not be found yet: counted only
        if role in self._no_peer_told:
            text = "still no %s peer: messages to it are not sent (see the first warning; Health: unroutable)"
            args: tuple[object, ...] = (role,)
        else:
            text = ("no %s peer known: messages to %s are not sent (counted in Health as unroutable). Start a %s "
                    "node, or give its address with --peer %s=HOST:PORT, or check that discovery browses the "
                    "interfaces it announces on (--interface); if this rig runs without %s on purpose, say so with "
                    "--absent %s (batteur rig does) or ignore this (said again at most every %g s)")
            args = (role, role, role, role, role, role, NO_PEER_LOG_INTERVAL_S)
        if self._no_peer_warnings.warn(role, now, text, *args):
            self._no_peer_told.add(role)

    def _resolve(self, host: str) -> str | None:
        """Numeric address of ``host`` for the socket's family: "" if unreachable, None while a name is looked up.

        Names are looked up off the event loop (``getaddrinfo`` may block for seconds) and
        cached; a stale entry is still used while its refresh runs.
        """
        address = _numeric(host, self._family)
        if address is None:
            return self._resolve_name(host)
        if not address:
            self._log_limited("family", logging.WARNING, "cannot reach IPv6 %s from an IPv4 socket", host)
        return address

    def _resolve_name(self, host: str) -> str | None:
        name = self._names.get(host)
        if name is None:
            if len(self._names) >= 1024:  # names come from config and discovery; this only bounds a runaway
                self._forget_idle_names()
            name = self._names[host] = _Name()
        age_s = self._clock() - name.stamp
        ttl_s = NAME_TTL_S if name.address else NAME_RETRY_S
        if name.task is None and (name.address is None or age_s >= ttl_s):
            name.task = self._start_lookup(host, name)
        return name.address

    def _start_lookup(self, host: str, name: _Name) -> asyncio.Task[None] | None:
        loop = self._loop
        if loop is None or loop.is_closed():
            name.address, name.stamp = "", self._clock()
            return None
        return loop.create_task(self._look_up(host, name))

    async def _look_up(self, host: str, name: _Name) -> None:
        """Resolve ``host`` in the loop's executor, then send what waited for it."""
        family = socket.AF_INET if self._family == socket.AF_INET else socket.AF_UNSPEC
        assert self._loop is not None
        try:
            infos = await self._loop.getaddrinfo(host, None, family=family, type=socket.SOCK_DGRAM)
            address = _numeric(str(infos[0][4][0]).split("%")[0], self._family) or ""
        # UnicodeError (a label over 63 bytes) is a ValueError; RuntimeError: the executor is shut down
        except (OSError, IndexError, ValueError, RuntimeError) as exc:
            self._log_limited(f"resolve:{host}", logging.WARNING, "cannot resolve %s: %s", host, exc)
            address = ""
        finally:
            name.task = None
        if address or not name.address:
            name.address, name.stamp = address, self._clock()
        else:  # a failed refresh: keep the last address (the host is likely still there), retry soon
            name.stamp = self._clock() - NAME_TTL_S + NAME_RETRY_S
        waiting, name.waiting = name.waiting, []
        for data, port, count in waiting:
            if address and self._transport is not None:
                self._transport.sendto(data, (address, port))
                self.stats.messages_out += count
            else:
                self.unroutable += count

    def _wait_for_name(self, host: str, data: bytes, port: int, count: int) -> None:
        name = self._names[host]
        if len(name.waiting) >= MAX_WAITING:
            self.unroutable += count
            self._log_limited(f"waiting:{host}", logging.WARNING, "not sent: %s still being looked up", host)
            return
        name.waiting.append((data, port, count))

    def _forget_idle_names(self) -> None:
        for host in [h for h, n in self._names.items() if n.task is None and not n.waiting]:
            del self._names[host]

    # -------------------------------------------------------------- receiving

    def _drain(self) -> None:
        """Read the datagrams already waiting on the socket, up to :data:`DRAIN_DATAGRAMS`.

        asyncio reads one datagram per loop iteration; a node whose loop runs back-to-back ticks (physics catching
        up) gets one iteration between them, so it read one message a tick while more arrived."""
        for _ in range(DRAIN_DATAGRAMS):
            if self.closed:
                return
            try:
                data, addr = self._sock.recvfrom(MAX_READ_BYTES)
            except (BlockingIOError, InterruptedError):
                return
            except OSError as exc:  # an ICMP error for an earlier send, as asyncio reports it
                self.send_errors += 1
                self._log_limited("socket", logging.WARNING, "socket error: %s", exc)
                continue
            self._receive(data, addr)

    def _receive(self, data: bytes, addr: tuple[Any, ...]) -> None:
        host = str(addr[0])
        if self._family == socket.AF_INET6 and host.startswith("::ffff:") and "." in host:
            host = host[7:]
        source = format_address(host, int(addr[1]))
        stats = self.stats
        if self.allow is not None and not self._allowed(host):
            stats.record_drop(DropReason.NOT_ALLOWED, "source not in the allow-list", source)
            return
        if len(data) > self.max_datagram:
            stats.record_drop(DropReason.OVERSIZE, f"{len(data)} bytes > {self.max_datagram}", source)
            return
        if self.max_rate is not None and not self._take_tokens(host, _message_count(data)):
            stats.record_drop(DropReason.RATE_LIMITED, f"over {self.max_rate:g} messages/s", source)
            return
        try:
            raws = parse_packet(data)
        except MessageError as exc:
            stats.record_drop(exc.reason, str(exc), source)
            return
        for raw in raws:
            try:
                message = to_model(raw, self.registry)
            except MessageError as exc:
                if exc.reason is DropReason.UNKNOWN_ADDRESS and self._route_raw(raw, source):
                    continue
                stats.record_drop(exc.reason, str(exc), source)
                if exc.reason in DECODE_REPLY_REASONS:
                    self._answer_undecodable(raw.address, exc, host, source, raw.args)
                    if self.on_undecodable is not None:
                        try:
                            self.on_undecodable(raw, exc, source)
                        except Exception as hook_exc:  # a hook bug must not stop the endpoint
                            self._log_limited("undecodable-hook", logging.WARNING, "undecodable hook failed: %s: %s",
                                              type(hook_exc).__name__, hook_exc)
                continue
            stats.messages_in += 1
            if self.tap is not None:
                self._tap_in(message)
            if self._handler is not None:
                try:
                    self._handler(message, source)
                except Exception as exc:  # a handler bug must not stop the endpoint
                    stats.record_drop(DropReason.HANDLER_ERROR, f"{raw.address}: {type(exc).__name__}: {exc}", source)
                    log.debug("handler error on %s", raw.address, exc_info=True)

    def _answer_undecodable(self, address: str, error: MessageError, host: str, source: str,
                            args: Sequence[Arg] = ()) -> None:
        """Tell the sender why its control message was dropped (:func:`decode_refusal`; only for this node's
        ``role``), within its host's reply budget; over it, count it in ``decode_unanswered``."""
        reply = decode_refusal(address, str(error), self.registry, self.role, args)
        if reply is None:
            return
        if not self._reply_budgets.take(host, self._clock()):
            self.decode_unanswered += 1
            return
        self.send(reply, source)

    def _tap_in(self, message: OscMessage) -> None:
        tap = self.tap
        if tap is not None:
            try:
                tap(message.ADDRESS, lambda: encode(message), "in")
            except Exception as exc:
                self._log_limited("tap", logging.WARNING, "tap failed: %s: %s", type(exc).__name__, exc)

    def _route_raw(self, raw: RawMessage, source: str) -> bool:
        for prefix, handler in self._raw_routes:
            if raw.address.startswith(prefix):
                self.stats.messages_in += 1
                if self.tap is not None:
                    try:
                        self.tap(raw.address, lambda: encode_raw(raw.address, raw.args), "in")
                    except Exception as exc:
                        self._log_limited("tap", logging.WARNING, "tap failed: %s: %s", type(exc).__name__, exc)
                try:
                    handler(raw, source)
                except Exception as exc:
                    self.stats.record_drop(
                        DropReason.HANDLER_ERROR, f"{raw.address}: {type(exc).__name__}: {exc}", source
                    )
                return True
        return False

    def _allowed(self, host: str) -> bool:
        known = self._allowed_cache.get(host)
        if known is None:
            try:
                ip = _unmap(ipaddress.ip_address(host.split("%")[0]))
                known = any(ip in net for net in self.allow or ())
            except ValueError:
                known = False
            if len(self._allowed_cache) > 4096:
                self._allowed_cache.clear()
            self._allowed_cache[host] = known
        return known

    def _take_tokens(self, host: str, count: int) -> bool:
        """Charge ``count`` messages to ``host``'s bucket; False (nothing charged) if it is empty.

        A bundle may take the bucket below zero (so one larger than the burst still passes, once);
        the debt is paid back at ``max_rate`` before the source is heard again.
        """
        assert self.max_rate is not None
        return self._buckets.take(host, self._clock(), count)

    def _log_limited(self, key: str, level: int, text: str, *args: object) -> None:
        now = self._clock()
        last = self._last_log.get(key)
        if last is None or now - last >= 5.0:
            if last is None and len(self._last_log) >= 1024:  # keys name hosts: keep the table bounded
                self._last_log.clear()
            self._last_log[key] = now
            log.log(level, text, *args)


def _message_count(data: bytes) -> int:
    """How many messages a packet holds, from the bundle element sizes alone (parsing costs ~12 us each): the
    codec's own walk (:func:`~common.messages.codec.walk_packet`). A malformed packet counts what could be walked
    (at least 1); the parser rejects it later."""
    return max(len(walk_packet(data)[0]), 1)


@functools.lru_cache(maxsize=1024)
def _numeric(host: str, family: int) -> str | None:
    """``host`` as a numeric address a socket of ``family`` can send to; "" if it cannot; None for a name."""
    try:
        ip = ipaddress.ip_address(host)
    except ValueError:
        return None
    if family == socket.AF_INET6 and isinstance(ip, ipaddress.IPv4Address):
        return f"::ffff:{ip}"
    if family == socket.AF_INET and isinstance(ip, ipaddress.IPv6Address):
        return str(ip.ipv4_mapped or "")
    return str(ip)


def _valid_target(host: object, port: object) -> bool:
    """True for a host and UDP port a datagram can go to (asyncio closes the whole transport on a bad port)."""
    return isinstance(host, str) and bool(host) and isinstance(port, int) and 0 < port < 65536


def _bind(host: str, port: int, rcvbuf_bytes: int) -> socket.socket:
    """A non-blocking UDP socket bound to ``host:port`` with a receive buffer of about ``rcvbuf_bytes``."""
    infos = socket.getaddrinfo(host, port, socket.AF_UNSPEC, socket.SOCK_DGRAM, 0, socket.AI_PASSIVE)
    if not infos:
        raise OSError(f"cannot resolve {host!r}")
    family, _, _, _, sockaddr = infos[0]
    sock = socket.socket(family, socket.SOCK_DGRAM)
    try:
        if family == socket.AF_INET6:
            # "::" listens on IPv4 too (as mapped addresses)
            sock.setsockopt(socket.IPPROTO_IPV6, socket.IPV6_V6ONLY, 0)
        set_receive_buffer(sock, rcvbuf_bytes)
        sock.bind(sockaddr)
        sock.setblocking(False)
    except BaseException:
        sock.close()
        raise
    return sock


def set_receive_buffer(sock: socket.socket, size: int) -> int:
    """Ask for a receive buffer of ``size`` bytes: SO_RCVBUFFORCE (root) first, else SO_RCVBUF.

    Returns the size the kernel granted (Linux reports twice the request, for
    its bookkeeping). Logs a warning if it is smaller than asked.
    """
    force: int | None = getattr(socket, "SO_RCVBUFFORCE", 33 if sys.platform.startswith("linux") else None)
    if force is not None:
        try:
            sock.setsockopt(socket.SOL_SOCKET, force, size)
        except OSError:
            force = None
    if force is None:
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, size)
        except OSError as exc:
            log.warning("cannot set the receive buffer: %s", exc)
    granted = sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)
    if granted < size:
        log.warning(
            "receive buffer is %d bytes, asked for %d (raise net.core.rmem_max or run as root); "
            "bursts may lose messages",
            granted,
            size,
        )
    return granted
