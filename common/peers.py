"""Who to send to: a table of peers by role, fed by discovery and static flags.

Static peers (``--peer sound=host:port``) override discovery for their role:
once a role has a static peer, discovered nodes of that role are ignored.
Every static peer given for a role is sent to (two sound servers: both play).
"""

from __future__ import annotations

import hashlib
import time
from collections.abc import Callable
from dataclasses import dataclass, field


@dataclass(frozen=True)
class Peer:
    """A node reachable over UDP."""

    role: str
    host: str
    port: int
    node_id: str = ""
    protocol: int = 0
    static: bool = False

    @property
    def address(self) -> tuple[str, int]:
        return (self.host, self.port)


def parse_static_peer(spec: str) -> Peer:
    """Parse ``ROLE=HOST:PORT`` (IPv6 hosts in brackets: ``sound=[::1]:9000``)."""
    if "=" not in spec:
        raise ValueError(f"peer {spec!r}: expected ROLE=HOST:PORT")
    role, _, hostport = spec.partition("=")
    if hostport.startswith("["):
        host, sep, port_text = hostport[1:].partition("]:")
    else:
        host, sep, port_text = hostport.rpartition(":")
    if not role or not host or not sep:
        raise ValueError(f"peer {spec!r}: expected ROLE=HOST:PORT")
    try:
        port = int(port_text)
    except ValueError:
        raise ValueError(f"peer {spec!r}: port {port_text!r} is not a number") from None
    if not 0 < port < 65536:
        raise ValueError(f"peer {spec!r}: port {port} out of range 1-65535")
    role = role.strip()
    return Peer(role=role, host=host, port=port, node_id=static_peer_id(role, host, port), static=True)


STATIC_ID_MAX = 64
"""Longest static peer id: it names the clock master in ``ClockStatus.master`` (at most 64 characters)."""


def static_peer_id(role: str, host: str, port: int) -> str:
    """``static:ROLE:HOST:PORT``, one id per address, so several static peers of a role are all kept (the same
    address given twice is one peer); a digest of the address where that would be longer than
    :data:`STATIC_ID_MAX`."""
    node_id = f"static:{role}:{host}:{port}"
    if len(node_id) <= STATIC_ID_MAX:
        return node_id
    digest = hashlib.sha256(f"{host}:{port}".encode()).hexdigest()[:16]
    return f"static:{role}"[: STATIC_ID_MAX - 17] + ":" + digest


@dataclass
class PeerTable:
    """Known peers by node id, with lookup by role. Static peers win over discovered ones."""

    clock: Callable[[], float] = time.monotonic
    _peers: dict[str, Peer] = field(default_factory=dict)
    _seen: dict[str, float] = field(default_factory=dict)
    listeners: list[Callable[[str, Peer], None]] = field(default_factory=list)

    def add(self, peer: Peer) -> None:
        """Add or update a peer; listeners get ("added" | "updated", peer)."""
        previous = self._peers.get(peer.node_id)
        self._peers[peer.node_id] = peer
        self._seen[peer.node_id] = self.clock()
        if previous != peer:
            for listener in self.listeners:
                listener("updated" if previous else "added", peer)

    def remove(self, node_id: str) -> None:
        peer = self._peers.pop(node_id, None)
        self._seen.pop(node_id, None)
        if peer is not None:
            for listener in self.listeners:
                listener("removed", peer)

    def for_role(self, role: str) -> list[Peer]:
        """Peers to send ``role`` messages to: the static ones if any, else those discovered."""
        static = [p for p in self._peers.values() if p.role == role and p.static]
        if static:
            return static
        return [p for p in self._peers.values() if p.role == role]

    def all(self) -> list[Peer]:
        return sorted(self._peers.values(), key=lambda p: (p.role, p.node_id))

    def __len__(self) -> int:
        return len(self._peers)
