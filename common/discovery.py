"""Find peers with zeroconf (mDNS / DNS-SD) and keep a :class:`~common.peers.PeerTable` up to date.

Each node registers one ``_osc._udp.local.`` service whose TXT record carries its role, Batteur
protocol version, node id and OSC port, and browses the same type for the roles it sends to.
Found peers are added to the peer table, peers that leave (goodbye packet, or no answer once their
records' TTL has run out) are removed, and a restarted node (new node id, or same node id on a new
port) is found again without restarting anybody else.

Interfaces are always explicit: the default is loopback only. Loopback addresses (127.0.0.0/8,
::1) are filtered out of LAN peers and preferred when the node itself runs on loopback.

Everything runs on python-zeroconf's asyncio API (:class:`AsyncZeroconf`,
:class:`AsyncServiceBrowser`, :class:`AsyncServiceInfo`). See docs/discovery.md.

``python -m common.discovery --help`` runs a node's discovery alone (used by the tests inside
network namespaces) or lists the nodes found.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import hashlib
import ipaddress
import json
import logging
import math
import os
import re
import signal
import sys
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import Annotated

import ifaddr
from pydantic import BaseModel, ConfigDict, Field, ValidationError
from zeroconf import (
    BadTypeInNameException,
    DNSQuestionType,
    NonUniqueNameException,
    ServiceStateChange,
    Zeroconf,
)
from zeroconf.asyncio import AsyncServiceBrowser, AsyncServiceInfo, AsyncZeroconf
from zeroconf.const import _CLASS_IN, _TYPE_SRV

from common.arg_types import count, non_negative, seconds, whole
from common.config import DEFAULT_RIG
from common.datafile import one_line
from common.messages.system import PROTOCOL_VERSION, NodeId, Role
from common.peers import Peer, PeerTable, parse_static_peer

log = logging.getLogger("batteur.discovery")

Network = ipaddress.IPv4Network | ipaddress.IPv6Network

SERVICE_TYPE = "_osc._udp.local."
"""DNS-SD service type every Batteur node registers (OSC over UDP)."""

LOOPBACK_INTERFACES: tuple[str, ...] = ("127.0.0.1",)
"""Default interfaces: loopback only. Listening on a LAN is an explicit choice."""

ALL_INTERFACES = "all"
"""Interface keyword that selects every IPv4 address of every adapter (explicit opt-in only)."""

LOOPBACK_NETWORKS: tuple[Network, ...] = (ipaddress.ip_network("127.0.0.0/8"), ipaddress.ip_network("::1/128"))
"""Implicit allow-list of a node on loopback only: it never sends to another machine."""

DEFAULT_TTL_S = 30
"""TTL of the records a node announces, seconds. A node that dies without a goodbye is dropped
by its peers at most about this long (plus one resolve timeout) after its last answer."""

_MAX_LABEL = 63  # bytes in one DNS label

QUESTION_TYPE = DNSQuestionType.QM
"""Ask for multicast answers only. Several nodes on one machine share UDP port 5353
(SO_REUSEPORT): a unicast answer (to a QU question) reaches only one of them, at random."""


class DiscoveryError(RuntimeError):
    """Discovery cannot start: bad interface, name already taken, zeroconf failure."""


class ServiceTxt(BaseModel):
    """The TXT record of a Batteur ``_osc._udp`` service (all values are strings on the wire)."""

    model_config = ConfigDict(frozen=True, extra="ignore")

    role: Role = Field(description="service role: physics, interaction, sound, graphics, ...")
    proto: Annotated[int, Field(ge=0)] = Field(description="Batteur OSC protocol version")
    node_id: NodeId = Field(description="unique id of the node process")
    port: Annotated[int, Field(ge=1, le=65535)] = Field(description="UDP port the node receives OSC on")
    rig: str = Field(default=DEFAULT_RIG, max_length=32, description="name of the node's rig (a node from before "
                     "8 Dec carries none: the default rig's)")

    def to_properties(self) -> dict[str, str]:
        """TXT key/value strings."""
        return {"role": self.role, "proto": str(self.proto), "node_id": self.node_id, "port": str(self.port),
                "rig": self.rig}

    @classmethod
    def from_properties(cls, properties: Mapping[str, str | None]) -> ServiceTxt:
        """Validate decoded TXT properties; raises :class:`pydantic.ValidationError`."""
        return cls.model_validate({k: v for k, v in properties.items() if v is not None})


class NodeInfo(BaseModel):
    """One node found on the network (what ``batteur ls`` prints)."""

    model_config = ConfigDict(frozen=True)

    role: str = Field(description="service role from the TXT record")
    node_id: str = Field(description="node id from the TXT record")
    host: str = Field(description="address chosen to reach the node ('' if none is usable)")
    port: int = Field(description="UDP port the node receives OSC on (from the SRV record)")
    protocol: int = Field(description="Batteur protocol version the node speaks")
    addresses: tuple[str, ...] = Field(default=(), description="every address the node announced")
    name: str = Field(default="", description="DNS-SD service instance name")
    rig: str = Field(default=DEFAULT_RIG, description="name of the node's rig (from the TXT record)")


@dataclass(frozen=True)
class Rejection:
    """A discovered service that was not added to the peer table, and why."""

    name: str
    reason: str  # "protocol", "txt", "address", "not_allowed", "rig"
    detail: str
    role: str = ""
    node_id: str = ""


@dataclass
class DiscoveryStats:
    """Counters of what discovery saw (totals since start)."""

    found: int = 0
    updated: int = 0
    lost: int = 0
    rejected_protocol: int = 0
    rejected_txt: int = 0
    rejected_address: int = 0
    rejected_not_allowed: int = 0
    rejected_rig: int = 0
    kept_quiet: int = 0
    """Peers kept after their mDNS records expired unanswered, because they still answered over unicast."""


# --------------------------------------------------------------------------- addresses and names


def is_loopback(address: str) -> bool:
    """True for 127.0.0.0/8 and ::1 (and IPv4-mapped loopback); False for anything unparsable."""
    try:
        ip = ipaddress.ip_address(address.split("%", 1)[0])
    except ValueError:
        return False
    if isinstance(ip, ipaddress.IPv6Address) and ip.ipv4_mapped is not None:
        return ip.ipv4_mapped.is_loopback
    return ip.is_loopback


def _address_rank(address: str, allow_loopback: bool, networks: Sequence[Network]) -> int | None:
    """Lower is better; None: unusable for this node."""
    try:
        ip = ipaddress.ip_address(address.split("%", 1)[0])
    except ValueError:
        return None
    if ip.is_unspecified or ip.is_multicast:
        return None
    loop = is_loopback(address)
    if loop and not allow_loopback:
        return None
    rank = 0 if loop else 10  # on loopback, loopback is preferred
    if not any(ip in net for net in networks if net.version == ip.version):
        rank += 4  # outside every network of our interfaces
    if ip.version == 6:
        rank += 2
        if ip.is_link_local and "%" not in address:
            rank += 1  # a link-local address without a scope is hard to use
    return rank


def choose_address(
    addresses: Iterable[str],
    allow_loopback: bool,
    networks: Sequence[Network] = (),
) -> str | None:
    """Pick the address to send to among those a peer announced.

    Parameters
    ----------
    addresses : iterable of str
        The peer's announced addresses (IPv6 link-local ones may carry ``%scope``).
    allow_loopback : bool
        Whether loopback addresses may be used (True when this node itself runs on loopback;
        they are then preferred). When False, 127.0.0.0/8 and ::1 are never chosen.
    networks : sequence of ip networks
        Networks of this node's interfaces; an address inside one of them is preferred.

    Returns
    -------
    str or None
        The best address (IPv4 before IPv6, same network before others), or None if none is usable.
    """
    best: tuple[int, int, str] | None = None
    for order, address in enumerate(addresses):
        rank = _address_rank(address, allow_loopback, networks)
        if rank is not None and (best is None or (rank, order) < best[:2]):
            best = (rank, order, address)
    return None if best is None else best[2]


def _adapters() -> list[ifaddr.Adapter]:
    return list(ifaddr.get_adapters())


def resolve_interfaces(interfaces: Sequence[str] | None) -> list[str]:
    """Turn interface names and addresses into the addresses zeroconf binds to.

    Parameters
    ----------
    interfaces : sequence of str or None
        Interface addresses (``"10.0.0.1"``, ``"fd00::1"``), interface names (``"eth0"``: all of
        its IPv4 addresses, or its IPv6 ones if it has none), or the single keyword ``"all"``
        (every IPv4 address of every adapter). None means loopback only (``127.0.0.1``).

    Returns
    -------
    list of str
        Unique addresses in the given order.

    Raises
    ------
    DiscoveryError
        An empty list, an unknown name, a wildcard address (0.0.0.0, ::) or an address that no
        local interface has.
    """
    if interfaces is None:
        return list(LOOPBACK_INTERFACES)
    if not interfaces:
        raise DiscoveryError("no interface given (use 127.0.0.1 for loopback)")
    adapters = _adapters()
    local: set[str] = set()
    by_name: dict[str, list[str]] = {}
    for adapter in adapters:
        v4 = [str(ip.ip) for ip in adapter.ips if isinstance(ip.ip, str)]
        v6 = [ip.ip[0] for ip in adapter.ips if isinstance(ip.ip, tuple)]
        by_name[adapter.nice_name] = v4 or v6
        by_name.setdefault(adapter.name, v4 or v6)
        local.update(v4)
        local.update(v6)
    result: list[str] = []
    for item in interfaces:
        item = item.strip()
        if item == ALL_INTERFACES:
            found = [str(ip.ip) for a in adapters for ip in a.ips if isinstance(ip.ip, str)]
        elif item in by_name:
            found = by_name[item]
            if not found:
                raise DiscoveryError(f"interface {item!r} has no address")
        else:
            try:
                ip = ipaddress.ip_address(item)
            except ValueError:
                known = ", ".join(sorted(by_name)) or "none"
                raise DiscoveryError(f"interface {item!r}: not an address nor a known name ({known})") from None
            if ip.is_unspecified:
                raise DiscoveryError(f"interface {item!r}: wildcard addresses are not allowed; name the interfaces")
            if str(ip) not in local:
                raise DiscoveryError(f"interface {item!r}: no local interface has this address")
            found = [str(ip)]
        result.extend(a for a in found if a not in result)
    if not result:
        raise DiscoveryError(f"interfaces {list(interfaces)!r} give no address")
    return result


def interface_networks(addresses: Iterable[str]) -> list[Network]:
    """Networks (address/prefix) of the local interfaces holding ``addresses``."""
    wanted = set(addresses)
    networks: list[Network] = []
    for adapter in _adapters():
        for ip in adapter.ips:
            addr = ip.ip if isinstance(ip.ip, str) else ip.ip[0]
            if addr in wanted:
                networks.append(ipaddress.ip_network(f"{addr}/{ip.network_prefix}", strict=False))
    return networks


def _label(text: str, allowed: str) -> str:
    """A DNS label from ``text``: other characters become '-', at most 63 bytes."""
    label = re.sub(f"[^{allowed}]", "-", text).strip("-") or "node"
    if len(label) > _MAX_LABEL:
        digest = hashlib.sha1(label.encode()).hexdigest()[:8]
        label = f"{label[: _MAX_LABEL - 9]}-{digest}"
    return label


def instance_name(role: str, node_id: str, type_: str = SERVICE_TYPE) -> str:
    """Full DNS-SD instance name of a node, e.g. ``sound-3f2a._osc._udp.local.``."""
    return f"{_label(f'{role}-{node_id}', 'A-Za-z0-9_-')}.{type_}"


def host_name(role: str, node_id: str) -> str:
    """mDNS host name a node announces its addresses under, e.g. ``batteur-sound-3f2a.local.``."""
    return f"{_label(f'batteur-{role}-{node_id}', 'A-Za-z0-9-')}.local."


def peer_from_service(
    name: str,
    srv_port: int | None,
    properties: Mapping[str, str | None],
    addresses: Sequence[str],
    *,
    allow_loopback: bool,
    protocol: int = PROTOCOL_VERSION,
    networks: Sequence[Network] = (),
    allowed: Sequence[Network] | None = None,
    rig: str | None = None,
) -> Peer | Rejection:
    """Decide what a resolved service means for the peer table (pure: no network).

    Parameters
    ----------
    name : str
        DNS-SD instance name.
    srv_port : int or None
        Port of the SRV record (authoritative; the TXT ``port`` is only cross-checked).
    properties : mapping
        Decoded TXT properties.
    addresses : sequence of str
        Announced addresses.
    allow_loopback : bool
        See :func:`choose_address`.
    protocol : int
        Our protocol version; a peer with another version is rejected.
    networks : sequence of ip networks
        Our interfaces' networks (preferred addresses).
    allowed : sequence of ip networks or None
        Allow-list: a peer whose chosen address is outside every one of them is rejected
        (``not_allowed``). None allows every address.
    rig : str or None
        Our rig's name: a node of another rig is rejected (``rig``). None takes every rig.

    Returns
    -------
    Peer or Rejection
    """
    try:
        txt = ServiceTxt.from_properties(properties)
    except ValidationError as exc:
        problems = "; ".join(f"{'.'.join(map(str, e['loc']))}: {e['msg']}" for e in exc.errors())
        return Rejection(name, "txt", f"bad TXT record ({problems})")
    if rig is not None and txt.rig != rig:
        return Rejection(name, "rig", f"of rig {txt.rig!r}, this node is of rig {rig!r}", txt.role, txt.node_id)
    if txt.proto != protocol:
        return Rejection(
            name, "protocol", f"speaks protocol {txt.proto}, we speak {protocol}", txt.role, txt.node_id
        )
    port = srv_port or txt.port
    if srv_port and srv_port != txt.port:
        log.warning("%s: SRV port %d differs from TXT port %d; using the SRV port", name, srv_port, txt.port)
    host = choose_address(addresses, allow_loopback, networks)
    if host is None:
        where = "loopback" if allow_loopback else "non-loopback"
        return Rejection(
            name, "address", f"no usable {where} address among {list(addresses)}", txt.role, txt.node_id
        )
    if allowed is not None and not _in_networks(host, allowed):
        return Rejection(
            name, "not_allowed", f"address {host} is not in the allow-list {[str(n) for n in allowed]}",
            txt.role, txt.node_id,
        )
    return Peer(role=txt.role, host=host, port=port, node_id=txt.node_id, protocol=txt.proto)


def _in_networks(address: str, networks: Sequence[Network]) -> bool:
    ip = ipaddress.ip_address(address.split("%", 1)[0])
    return any(ip in net for net in networks if net.version == ip.version)


def parse_networks(specs: Iterable[str]) -> list[Network]:
    """Parse an allow-list of addresses or CIDRs (``10.0.0.0/24``, ``192.168.1.7``, ``fd00::/64``).

    Raises
    ------
    DiscoveryError
        On an entry that is neither.
    """
    networks: list[Network] = []
    for spec in specs:
        try:
            networks.append(ipaddress.ip_network(spec.strip(), strict=False))
        except ValueError:
            raise DiscoveryError(f"allow-list entry {spec!r} is not an address or network") from None
    return networks


def _info_addresses(info: AsyncServiceInfo) -> list[str]:
    return list(info.parsed_scoped_addresses())


# --------------------------------------------------------------------------- the discovery service


class Discovery:
    """Register this node and keep ``peers`` filled with the nodes of ``browse_roles``.

    Parameters
    ----------
    role, node_id : str
        This node's role and unique id (announced in TXT; our own service is never a peer).
    port : int
        UDP port this node receives OSC on.
    interfaces : sequence of str or None
        Interface addresses or names to run mDNS on (see :func:`resolve_interfaces`).
        None: loopback only.
    peers : PeerTable
        Table to add found peers to and remove lost ones from. Static peers already in it keep
        overriding discovered ones for their role (``PeerTable.for_role``).
    browse_roles : sequence of str
        Roles to add to the table; services of other roles are ignored.
    protocol : int
        Protocol version announced and required of peers.
    host_addresses : sequence of str or None
        Addresses to announce; default: the interface addresses.
    allow_loopback : bool or None
        Accept (and prefer) loopback peer addresses. None: True when every interface address is
        loopback, False otherwise (LAN peers never get a 127.x / ::1 address).
    ttl_s : int
        TTL of our records, seconds (how long a crashed node lingers at its peers).
    check_interval_s : float
        How often known peers are checked against the cache (and re-queried once their records
        have expired), seconds.
    resolve_timeout_s : float
        How long to wait for a service's records, seconds.
    retry_interval_s : float
        How often a peer dropped for not answering is asked for again (until the browser
        forgets its name), seconds.
    extra_services : sequence of AsyncServiceInfo
        More services registered (and unregistered) with this one, e.g. OSCQuery ``_oscjson._tcp``
        (or use :meth:`register_extra`).
    allowed : sequence of str or None
        Allow-list of peer addresses or networks (CIDR) for LAN use; peers elsewhere are rejected.
        None: every address, except for a node on loopback only, which accepts loopback peers only.
    rig : str
        Name of this node's rig, announced in TXT; nodes of another rig are ignored (two classes' rigs
        on one network). Default: one shared name.
    still_answers : callable or None
        Whether a peer answered over unicast lately (the node's Health and clock pongs). A peer whose
        records expired and who does not answer the re-query is kept while this says True (multicast
        filtered on the way, the peer still running), with one warning; None: such peers are dropped.
    """

    def __init__(
        self,
        role: str,
        node_id: str,
        port: int,
        interfaces: Sequence[str] | None = None,
        peers: PeerTable | None = None,
        browse_roles: Sequence[str] = (),
        protocol: int = PROTOCOL_VERSION,
        host_addresses: Sequence[str] | None = None,
        allow_loopback: bool | None = None,
        *,
        ttl_s: int = DEFAULT_TTL_S,
        check_interval_s: float = 1.0,
        resolve_timeout_s: float = 3.0,
        retry_interval_s: float = 10.0,
        extra_services: Sequence[AsyncServiceInfo] = (),
        allowed: Sequence[str] | None = None,
        rig: str = DEFAULT_RIG,
        still_answers: Callable[[Peer], bool] | None = None,
    ) -> None:
        self.txt = ServiceTxt(role=role, proto=protocol, node_id=node_id, port=port, rig=rig)
        if ttl_s < 1:
            raise ValueError(f"ttl_s must be at least 1 second, got {ttl_s}")
        self.role = role
        self.node_id = node_id
        self.port = port
        self.protocol = protocol
        self.interfaces = list(interfaces) if interfaces is not None else None
        self.peers = peers if peers is not None else PeerTable()
        self.browse_roles = frozenset(browse_roles)
        self.host_addresses = list(host_addresses) if host_addresses is not None else None
        for address in self.host_addresses or ():
            try:
                ipaddress.ip_address(address)
            except ValueError:
                raise ValueError(f"host address {address!r} is not an IP address") from None
        self.allow_loopback = allow_loopback
        self.ttl_s = ttl_s
        self.check_interval_s = check_interval_s
        self.resolve_timeout_s = resolve_timeout_s
        self.retry_interval_s = retry_interval_s
        self.stats = DiscoveryStats()
        self.rejection_listeners: list[Callable[[Rejection], None]] = []
        self.info: AsyncServiceInfo | None = None
        self.allowed = parse_networks(allowed) if allowed is not None else None
        self.rig = rig
        self.still_answers = still_answers
        self._quiet: dict[str, float] = {}  # name of a peer kept though mDNS is silent -> next re-query (loop time)
        self._quiet_warned = False
        self._extra: list[AsyncServiceInfo] = list(extra_services)
        self._pending_extra: list[tuple[str, str, int, dict[str, str]]] = []
        self._aiozc: AsyncZeroconf | None = None
        self._browser: AsyncServiceBrowser | None = None
        self._addresses: list[str] = []
        self._networks: list[Network] = []
        self._known: set[str] = set()  # instance names the browser reports present
        self._by_name: dict[str, str] = {}  # instance name -> node id we put in the table
        self._received_ms: dict[str, float] = {}  # node id in the table -> when its SRV record was last received
        self._silent: dict[str, float] = {}  # name of a peer dropped for not answering -> next retry (loop time)
        self._tasks: dict[str, asyncio.Task[None]] = {}
        self._warned: set[tuple[str, str, str]] = set()
        self._sweeper: asyncio.Task[None] | None = None
        self._background: set[asyncio.Task[object]] = set()

    # ---- lifecycle

    @property
    def addresses(self) -> list[str]:
        """Interface addresses in use (after :meth:`start`)."""
        return list(self._addresses)

    @property
    def loopback_allowed(self) -> bool:
        """Whether loopback peer addresses are accepted (resolved after :meth:`start`)."""
        if self.allow_loopback is not None:
            return self.allow_loopback
        return bool(self._addresses) and all(is_loopback(a) for a in self._addresses)

    @property
    def effective_allowed(self) -> Sequence[Network] | None:
        """The allow-list in force: ``allowed``, or loopback only for a node on loopback only."""
        if self.allowed is not None:
            return self.allowed
        if self._addresses and all(is_loopback(a) for a in self._addresses):
            return LOOPBACK_NETWORKS
        return None

    @property
    def zeroconf(self) -> Zeroconf:
        if self._aiozc is None:
            raise DiscoveryError("discovery is not started")
        return self._aiozc.zeroconf

    async def start(self) -> None:
        """Open mDNS on the interfaces, browse, and register this node (about 1 s of probing)."""
        if self._aiozc is not None:
            return
        self._addresses = resolve_interfaces(self.interfaces)
        self._networks = interface_networks(self._addresses)
        try:
            self._aiozc = AsyncZeroconf(interfaces=list(self._addresses))
        except OSError as exc:
            raise DiscoveryError(f"cannot open mDNS on {self._addresses}: {exc}") from exc
        self._browser = AsyncServiceBrowser(
            self.zeroconf, SERVICE_TYPE, handlers=[self._on_state_change], question_type=QUESTION_TYPE
        )
        self.info = self._service_info(SERVICE_TYPE, instance_name(self.role, self.node_id), self.port,
                                       self.txt.to_properties())
        try:
            await self._register(self.info)
            for type_, name, port, properties in self._pending_extra:
                self._extra.append(self._service_info(type_, name, port, properties))
            self._pending_extra.clear()
            for extra in self._extra:
                await self._register(extra)
        except BaseException:
            await self.stop()
            raise
        self._sweeper = asyncio.create_task(self._sweep_forever(), name=f"discovery-sweep-{self.node_id}")
        log.info(
            "discovery: %s %s on %s registered as %s (port %d); browsing %s",
            self.role, self.node_id, self._addresses, self.info.name, self.port, sorted(self.browse_roles),
        )

    async def stop(self) -> None:
        """Send goodbyes for our services, stop browsing, and drop the peers discovery added."""
        if self._aiozc is None:
            return
        aiozc, self._aiozc = self._aiozc, None
        tasks = [t for t in (self._sweeper, *self._tasks.values(), *self._background) if t is not None]
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
        self._sweeper = None
        self._tasks.clear()
        self._background.clear()
        if self._browser is not None:
            await self._browser.async_cancel()
            self._browser = None
        try:
            await aiozc.async_unregister_all_services()  # goodbye packets
        finally:
            await aiozc.async_close()
            for name in list(self._by_name):
                self._forget(name, "discovery stopped", count=False)
            self._known.clear()
            self._silent.clear()
            self._quiet.clear()

    async def __aenter__(self) -> Discovery:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.stop()

    async def register_extra(
        self, type_: str, port: int, txt: Mapping[str, str], name: str | None = None
    ) -> AsyncServiceInfo | None:
        """Register another service of this node (e.g. OSCQuery ``_oscjson._tcp.local.``).

        Parameters
        ----------
        type_ : str
            Full service type, e.g. ``"_oscjson._tcp.local."``.
        port : int
            Port of that service.
        txt : mapping of str to str
            Its TXT properties.
        name : str or None
            Instance label; default ``<role>-<node id>``.

        Returns
        -------
        AsyncServiceInfo or None
            The registered info (unregistered by :meth:`stop`), or None before :meth:`start`: the
            service is then queued and registered at start (with the interface addresses).
        """
        if not 0 < port < 65536:
            raise ValueError(f"extra service {type_}: port {port} out of range 1-65535")
        if name is None:
            full = instance_name(self.role, self.node_id, type_)
        else:
            full = f"{_label(name, 'A-Za-z0-9_ -')}.{type_}"
        if self._aiozc is None:
            self._pending_extra.append((type_, full, port, dict(txt)))
            return None
        info = self._service_info(type_, full, port, dict(txt))
        self._extra.append(info)
        await self._register(info)
        return info

    def _service_info(self, type_: str, name: str, port: int, properties: dict[str, str]) -> AsyncServiceInfo:
        advertised = self.host_addresses if self.host_addresses is not None else self._addresses
        try:
            return AsyncServiceInfo(
                type_,
                name,
                port=port,
                properties=properties,
                server=host_name(self.role, self.node_id),
                parsed_addresses=list(advertised),
                host_ttl=self.ttl_s,
                other_ttl=self.ttl_s,
            )
        except BadTypeInNameException as exc:
            raise DiscoveryError(f"bad service type or name {type_!r} / {name!r}") from exc

    async def _register(self, info: AsyncServiceInfo) -> None:
        if self._aiozc is None:
            return
        try:
            announced = await self._aiozc.async_register_service(info)
        except NonUniqueNameException:
            raise DiscoveryError(
                f"{info.name} is already registered by another node (node ids must be unique)"
            ) from None
        task = asyncio.ensure_future(announced)
        self._background.add(task)
        task.add_done_callback(self._background.discard)

    # ---- browsing

    def _on_state_change(
        self, zeroconf: Zeroconf, service_type: str, name: str, state_change: ServiceStateChange
    ) -> None:
        if state_change is ServiceStateChange.Removed:
            if name in self._quiet and self._answers(name):
                return  # its PTR ran out unrefreshed (mDNS filtered); it still answers: kept, re-queried as before
            self._known.discard(name)
            self._silent.pop(name, None)
            self._cancel(name)
            self._forget(name, "said goodbye")
            return
        self._known.add(name)
        self._resolve_soon(name, from_cache_only=False)

    def _cancel(self, name: str) -> None:
        task = self._tasks.pop(name, None)
        if task is not None:
            task.cancel()

    def _resolve_soon(self, name: str, from_cache_only: bool) -> None:
        if self._aiozc is None:
            return
        if from_cache_only and name in self._tasks:
            return
        self._cancel(name)
        task = asyncio.create_task(self._resolve(name, from_cache_only))
        self._tasks[name] = task

        def done(t: asyncio.Task[None], name: str = name) -> None:
            if self._tasks.get(name) is t:
                del self._tasks[name]

        task.add_done_callback(done)

    async def _resolve(self, name: str, from_cache_only: bool) -> None:
        info = AsyncServiceInfo(SERVICE_TYPE, name)
        zc = self.zeroconf
        if info.load_from_cache(zc):
            if self._quiet.pop(name, None) is not None:
                log.info("discovery: %s answers mDNS again", name)
            self._apply(name, info, self._srv_received_ms(name))
            return
        if from_cache_only and name in self._quiet:
            # kept though mDNS is silent: dropped once it stops answering over unicast too; re-queried now and then
            now = asyncio.get_running_loop().time()
            if not self._answers(name):
                self._quiet.pop(name, None)
                self._forget(name, "no answer to mDNS since its records expired, and none over unicast now either")
                self._silent[name] = now + self.retry_interval_s
                return
            if now < self._quiet[name]:
                return
            self._quiet[name] = now + self.retry_interval_s
        if from_cache_only and name not in self._by_name:
            # Not a peer right now. A peer that stopped answering (stalled, unplugged) may come back
            # without announcing itself again: ask for it now and then until the browser drops it.
            now = asyncio.get_running_loop().time()
            if name not in self._silent or now < self._silent[name]:
                return
            self._silent[name] = now + self.retry_interval_s
        if await info.async_request(zc, self.resolve_timeout_s * 1000, question_type=QUESTION_TYPE):
            self._silent.pop(name, None)
            if self._quiet.pop(name, None) is not None:
                log.info("discovery: %s answers mDNS again", name)
            self._apply(name, info, self._srv_received_ms(name))
        elif name in self._quiet:
            return  # still kept (checked at each sweep against its unicast answers)
        elif name in self._by_name and self._answers(name):
            self._keep_quiet(name)
        elif name in self._by_name:
            self._forget(name, f"no answer within {self.resolve_timeout_s:g} s after its records expired")
            self._silent[name] = asyncio.get_running_loop().time() + self.retry_interval_s
        else:
            log.debug("discovery: %s did not resolve", name)

    def _answers(self, name: str) -> bool:
        """Whether the peer discovery added under ``name`` still answers over unicast (:attr:`still_answers`)."""
        node_id = self._by_name.get(name)
        peer = next((p for p in self.peers.all() if p.node_id == node_id), None)
        return peer is not None and self.still_answers is not None and self.still_answers(peer)

    def _keep_quiet(self, name: str) -> None:
        """Keep the peer of ``name``: its records expired and it did not answer the re-query, yet it answers over
        unicast. Multicast is lost on the way (a firewall, Wi-Fi client isolation): warned about once, the first
        time (until 8 Dec such peers were dropped ~30 s after the start, both sides' traffic lost)."""
        self._quiet[name] = asyncio.get_running_loop().time() + self.retry_interval_s
        self.stats.kept_quiet += 1
        node_id = self._by_name.get(name, "")
        peer = next((p for p in self.peers.all() if p.node_id == node_id), None)
        where = f"{peer.role} {node_id} at {peer.host}:{peer.port}" if peer is not None else name
        if self._quiet_warned:
            log.info("discovery: %s does not answer mDNS since its records expired but answers over unicast: kept",
                     where)
            return
        self._quiet_warned = True
        log.warning("discovery has gone quiet on %s: %s no longer answers mDNS since its records expired, yet it "
                    "answers over unicast, so it is kept (and so are the others like it). Multicast filtered (a "
                    "firewall, Wi-Fi client isolation)? Nodes started from now on are not found; static peers "
                    "(--peer ROLE=HOST:PORT) do not depend on multicast (docs/deployment.md)",
                    ", ".join(self._addresses), where)

    def _srv_received_ms(self, name: str) -> float:
        """When the SRV record of ``name`` in the cache was last received (zeroconf's clock, ms); infinity if
        it is not there (taken as fresh)."""
        if self._aiozc is None:
            return math.inf
        record = self.zeroconf.cache.get_by_details(name, _TYPE_SRV, _CLASS_IN)
        return float(record.created) if record is not None else math.inf

    def _apply(self, name: str, info: AsyncServiceInfo, received_ms: float = math.inf) -> None:
        """Put the node ``info`` describes in the peer table (or reject it). ``received_ms``: when its records
        were last received, to tell a live node from a crashed one whose records linger in the cache on the
        same host:port (the fresher wins)."""
        result = peer_from_service(
            name,
            info.port,
            info.decoded_properties,
            _info_addresses(info),
            allow_loopback=self.loopback_allowed,
            protocol=self.protocol,
            networks=self._networks,
            allowed=self.effective_allowed,
            rig=self.rig,
        )
        if isinstance(result, Rejection):
            if result.node_id == self.node_id:
                return
            self._reject(result)
            self._forget(name, result.detail)
            return
        peer = result
        if peer.node_id == self.node_id or peer.role not in self.browse_roles:
            return
        rivals = [other for other in self.peers.all()
                  if not other.static and other.node_id != peer.node_id and other.address == peer.address]
        if any(self._received_ms.get(other.node_id, -math.inf) > received_ms for other in rivals):
            # Records older than those of the node now at this address: a node that crashed there, its records
            # still in the cache (up to ttl_s). Re-read at every sweep, they must not swap it back in.
            log.debug("discovery: %s %s at %s:%d is stale: a node with fresher records holds that address",
                      peer.role, peer.node_id, peer.host, peer.port)
            return
        previous_id = self._by_name.get(name)
        if previous_id is not None and previous_id != peer.node_id:
            self._forget(name, f"replaced by node {peer.node_id}", count=False)
        for other in rivals:
            if other.node_id in {p.node_id for p in self.peers.all()}:
                log.info("discovery: %s %s at %s:%d replaced by %s", other.role, other.node_id, *other.address,
                         peer.node_id)
                self._drop_node(other.node_id)
        known = next((p for p in self.peers.all() if p.node_id == peer.node_id), None)
        if known is None:
            self.stats.found += 1
            log.info("discovery: found %s %s at %s:%d", peer.role, peer.node_id, peer.host, peer.port)
        elif known != peer:
            self.stats.updated += 1
            log.info("discovery: %s %s moved to %s:%d", peer.role, peer.node_id, peer.host, peer.port)
        self._by_name[name] = peer.node_id
        self._received_ms[peer.node_id] = received_ms
        self.peers.add(peer)

    def _reject(self, rejection: Rejection) -> None:
        key = (rejection.name, rejection.reason, rejection.detail)
        if key in self._warned:
            return
        self._warned.add(key)
        if rejection.reason == "protocol":
            self.stats.rejected_protocol += 1
        elif rejection.reason == "txt":
            self.stats.rejected_txt += 1
        elif rejection.reason == "not_allowed":
            self.stats.rejected_not_allowed += 1
        elif rejection.reason == "rig":
            self.stats.rejected_rig += 1
        else:
            self.stats.rejected_address += 1
        # another rig's node is expected on a shared network (two classes): said once, quietly
        level = logging.INFO if rejection.reason == "rig" else logging.WARNING
        log.log(level, "discovery: ignoring %s: %s", rejection.name, rejection.detail)
        for listener in self.rejection_listeners:
            listener(rejection)

    def _drop_node(self, node_id: str) -> None:
        for name, known in list(self._by_name.items()):
            if known == node_id:
                del self._by_name[name]
        self._received_ms.pop(node_id, None)
        self.peers.remove(node_id)

    def _forget(self, name: str, why: str, count: bool = True) -> None:
        self._quiet.pop(name, None)
        node_id = self._by_name.pop(name, None)
        if node_id is None:
            return
        if node_id in self._by_name.values():
            return  # the node is still reachable under another name
        if count:
            self.stats.lost += 1
            log.info("discovery: lost %s (%s)", node_id, why)
        self._received_ms.pop(node_id, None)
        self.peers.remove(node_id)

    async def _sweep_forever(self) -> None:
        """Re-check every known service: refresh from the cache, re-query expired ones."""
        while True:
            await asyncio.sleep(self.check_interval_s)
            for name in list(self._known):
                self._resolve_soon(name, from_cache_only=True)


# --------------------------------------------------------------------------- listing


async def browse_nodes(
    timeout_s: float = 3.0,
    interfaces: Sequence[str] | None = None,
    allow_loopback: bool | None = None,
    type_: str = SERVICE_TYPE,
) -> list[NodeInfo]:
    """List the Batteur nodes answering on ``interfaces`` within ``timeout_s`` (for ``batteur ls``).

    Nodes of every role and protocol version are listed; a node whose TXT record is not a Batteur
    record is skipped. ``host`` is the address :func:`choose_address` picks ('' if none fits).

    Parameters
    ----------
    timeout_s : float
        How long to browse, seconds. Responders may hold an answer back by up to about 1.6 s
        (RFC 6762 flood protection when the record was multicast in the last second), so less
        than 2 s can miss nodes.
    interfaces : sequence of str or None
        See :func:`resolve_interfaces`; None is loopback only.
    allow_loopback : bool or None
        See :class:`Discovery`.
    type_ : str
        Service type to browse.

    Returns
    -------
    list of NodeInfo
        Sorted by role then node id.
    """
    addresses = resolve_interfaces(interfaces)
    networks = interface_networks(addresses)
    loopback = allow_loopback if allow_loopback is not None else all(is_loopback(a) for a in addresses)
    names: set[str] = set()

    def on_change(zeroconf: Zeroconf, service_type: str, name: str, state_change: ServiceStateChange) -> None:
        if state_change is ServiceStateChange.Removed:
            names.discard(name)
        else:
            names.add(name)

    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout_s
    async with AsyncZeroconf(interfaces=list(addresses)) as aiozc:
        browser = AsyncServiceBrowser(aiozc.zeroconf, type_, handlers=[on_change], question_type=QUESTION_TYPE)
        try:
            await asyncio.sleep(max(0.0, timeout_s * 0.7))
            remaining_ms = max(200.0, (deadline - loop.time()) * 1000)

            async def resolve(name: str) -> NodeInfo | None:
                try:
                    info = AsyncServiceInfo(type_, name)
                    if not await info.async_request(aiozc.zeroconf, remaining_ms, question_type=QUESTION_TYPE):
                        return None
                    txt = ServiceTxt.from_properties(info.decoded_properties)
                except ValidationError:
                    log.info("ls: %s has no valid Batteur TXT record", name)
                    return None
                except Exception as exc:  # an odd record from another program: skip it, list the others
                    log.info("ls: %s cannot be resolved: %s: %s", name, type(exc).__name__, exc)
                    return None
                addrs = _info_addresses(info)
                return NodeInfo(
                    role=txt.role,
                    node_id=txt.node_id,
                    host=choose_address(addrs, loopback, networks) or "",
                    port=info.port or txt.port,
                    protocol=txt.proto,
                    addresses=tuple(addrs),
                    name=name,
                    rig=txt.rig,
                )

            found = await asyncio.gather(*(resolve(n) for n in sorted(names)))
        finally:
            await browser.async_cancel()
    return sorted((n for n in found if n is not None), key=lambda n: (n.role, n.node_id))


# --------------------------------------------------------------------------- command line

CLI_DESCRIPTION = """\
Run one node's discovery alone, or list the Batteur nodes zeroconf finds (see docs/discovery.md).

  run  registers a node (role, node id, OSC port) and prints one JSON line per event:
       started, added, updated, removed, rejected, stopped (or error); stops on Ctrl-C or SIGTERM.
  ls   prints one JSON line per node found (role, node_id, host, port, protocol, addresses, name).

mDNS runs on loopback unless --interface names others."""


class _OutputClosed(Exception):
    """The reader of our standard output has gone (``... ls | head``)."""


def _emit(record: dict[str, object]) -> None:
    try:
        print(json.dumps(record, sort_keys=True), flush=True)
    except BrokenPipeError:
        # point stdout at /dev/null so the interpreter's last flush stays quiet; `run` keeps announcing
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
        raise _OutputClosed from None


def _peer_json(peer: Peer) -> dict[str, object]:
    return asdict(peer)


@dataclass
class _RunState:
    stop: asyncio.Event = field(default_factory=asyncio.Event)


def _extra_service(spec: str) -> tuple[str, int]:
    """``TYPE:PORT`` of ``--extra``; ValueError saying what is wrong."""
    type_, _, port = spec.rpartition(":")
    if not type_ or not port.isdigit() or not 0 < int(port) < 65536:
        raise ValueError(f"--extra {spec!r}: expected TYPE:PORT with a port 1-65535, e.g. _oscjson._tcp.local.:8080")
    return type_, int(port)


async def _run_node(args: argparse.Namespace) -> int:
    peers = PeerTable()
    roles = sorted(set(args.browse))

    def on_peer(kind: str, peer: Peer) -> None:
        with contextlib.suppress(_OutputClosed):
            _emit({"event": kind, "peer": _peer_json(peer),
                   "for_role": {r: [_peer_json(p) for p in peers.for_role(r)] for r in roles}})

    def on_rejection(rejection: Rejection) -> None:
        with contextlib.suppress(_OutputClosed):
            _emit({"event": "rejected", **asdict(rejection)})

    try:
        for spec in args.peer:
            peers.add(parse_static_peer(spec))
        peers.listeners.append(on_peer)
        extras = [_extra_service(spec) for spec in args.extra]
        discovery = Discovery(
            args.role, args.node_id, args.port, args.interface or None, peers, roles,
            protocol=args.proto, host_addresses=args.host_address or None, allow_loopback=args.allow_loopback,
            ttl_s=args.ttl, check_interval_s=args.check_interval, resolve_timeout_s=args.resolve_timeout,
            retry_interval_s=args.retry_interval, allowed=args.allow or None, rig=args.rig,
        )
        discovery.rejection_listeners.append(on_rejection)
        for type_, port in extras:
            await discovery.register_extra(type_, port, {"role": args.role, "node_id": args.node_id})
        await discovery.start()
    except (DiscoveryError, ValueError) as exc:
        _emit({"event": "error", "detail": one_line(exc)})
        return 2
    state = _RunState()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, state.stop.set)
    with contextlib.suppress(_OutputClosed):
        _emit({"event": "started", "name": discovery.info.name if discovery.info else "",
               "addresses": discovery.addresses, "port": args.port, "node_id": args.node_id})
    with contextlib.suppress(asyncio.TimeoutError):
        await asyncio.wait_for(state.stop.wait(), args.duration if args.duration > 0 else None)
    await discovery.stop()
    with contextlib.suppress(_OutputClosed):
        _emit({"event": "stopped", "stats": asdict(discovery.stats)})
    return 0


async def _run_ls(args: argparse.Namespace) -> int:
    nodes = await browse_nodes(args.timeout, args.interface or None, args.allow_loopback)
    for node in nodes:
        _emit(node.model_dump(mode="json"))
    return 0


def _port(text: str) -> int:
    """A UDP port, 1-65535."""
    value = whole(text)
    if not 0 < value < 65536:
        raise argparse.ArgumentTypeError(f"{text!r}: give a port from 1 to 65535")
    return value


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m common.discovery", description=CLI_DESCRIPTION,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("-v", "--verbose", action="store_true", help="log at debug level")
    sub = parser.add_subparsers(dest="command", required=True, metavar="{run,ls}")
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--interface", action="append", default=[],
                        help="interface address or name (repeatable; 'all' = every IPv4 address); default 127.0.0.1")
    common.add_argument("--allow-loopback", action=argparse.BooleanOptionalAction, default=None,
                        help="accept loopback peer addresses (default: only when on loopback)")
    run = sub.add_parser("run", parents=[common], help="register a node and print peer events as JSON lines",
                         description="Register a node and print peer events as JSON lines until Ctrl-C or SIGTERM.")
    run.add_argument("--role", required=True, help="role to announce (lower case: sound, physics, ...)")
    run.add_argument("--node-id", required=True, help="unique node id to announce (letters, digits, _ . : -)")
    run.add_argument("--port", type=_port, required=True, help="OSC UDP port to announce (1-65535)")
    run.add_argument("--browse", action="append", default=[], help="role to look for (repeatable)")
    run.add_argument("--peer", action="append", default=[], help="static peer ROLE=HOST:PORT (repeatable)")
    run.add_argument("--proto", type=whole, default=PROTOCOL_VERSION, help="protocol version to announce")
    run.add_argument("--rig", default=DEFAULT_RIG, help=f"rig name to announce; nodes of another rig are ignored "
                     f"(default {DEFAULT_RIG})")
    run.add_argument("--ttl", type=count, default=DEFAULT_TTL_S, help="TTL of our records, whole seconds")
    run.add_argument("--check-interval", type=seconds, default=1.0, help="peer re-check period, seconds")
    run.add_argument("--retry-interval", type=seconds, default=10.0,
                     help="re-ask a peer dropped for not answering this often, seconds")
    run.add_argument("--resolve-timeout", type=seconds, default=3.0, help="wait for a service's records, seconds")
    run.add_argument("--extra", action="append", default=[],
                     help="extra service TYPE:PORT to register, e.g. _oscjson._tcp.local.:8080 (repeatable)")
    run.add_argument("--allow", action="append", default=[],
                     help="allow-list: peer address or CIDR (repeatable; default: any)")
    run.add_argument("--host-address", action="append", default=[],
                     help="address to announce (repeatable; default: the interface addresses)")
    run.add_argument("--duration", type=non_negative, default=0.0,
                     help="stop after this many seconds (0: until a signal)")
    ls = sub.add_parser("ls", parents=[common], help="list nodes found as JSON lines",
                        description="List the Batteur nodes found, one JSON line each (any protocol version).")
    ls.add_argument("--timeout", type=seconds, default=3.0, help="browse time, seconds (default 3; less than 2 "
                    "can miss nodes)")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.INFO, stream=sys.stderr,
                        format="%(asctime)s %(name)s %(levelname)s %(message)s")
    if args.verbose:
        logging.getLogger("zeroconf").setLevel(logging.DEBUG)
    runner = _run_node if args.command == "run" else _run_ls
    prog = f"python -m common.discovery {args.command}"
    try:
        return asyncio.run(runner(args))
    except _OutputClosed:  # `ls | head`: the reader has what it wanted
        return 0
    except (DiscoveryError, ValueError, OSError) as exc:  # a bad --interface, mDNS that cannot start
        print(f"{prog}: {one_line(exc)}", file=sys.stderr)
        return 2 if isinstance(exc, (DiscoveryError, ValueError)) else 1
    except KeyboardInterrupt:
        print(f"\n{prog}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
