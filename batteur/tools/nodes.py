"""Finding nodes for the command-line tools: explicit ``HOST:PORT`` or zeroconf discovery."""

from __future__ import annotations

import ipaddress
import socket
from collections.abc import Sequence
from dataclasses import dataclass

from common.peers import parse_static_peer


@dataclass(frozen=True)
class Target:
    """A node to talk to."""

    host: str
    port: int
    role: str = "?"
    node_id: str = ""

    @property
    def address(self) -> str:
        return f"[{self.host}]:{self.port}" if ":" in self.host else f"{self.host}:{self.port}"


def bind_address(targets: Sequence[Target]) -> str:
    """Where a tool should listen to hear answers from ``targets``: loopback unless one is elsewhere."""
    remote = [t for t in targets if not ipaddress_is_loopback(t.host)]
    if not remote:
        return "127.0.0.1"
    return "::" if any(":" in t.host for t in remote) else "0.0.0.0"


def target_networks(targets: Sequence[Target]) -> list[str]:
    """Allow-list for a tool listening off loopback: only the targets themselves may answer."""
    networks: list[str] = []
    for target in targets:
        if ipaddress_is_loopback(target.host):
            continue
        try:
            addresses = [ipaddress.ip_address(target.host)]
        except ValueError:  # a host name: every address it resolves to
            infos = socket.getaddrinfo(target.host, target.port, type=socket.SOCK_DGRAM)
            addresses = [ipaddress.ip_address(info[4][0]) for info in infos]
        networks += [f"{a}/{a.max_prefixlen}" for a in addresses]
    return networks


def ipaddress_is_loopback(host: str) -> bool:
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return host == "localhost"


def parse_node(spec: str) -> Target:
    """``HOST:PORT`` (or ``[v6]:PORT``) as a target; raises ValueError."""
    peer = parse_static_peer(f"node={spec}")
    return Target(peer.host, peer.port)


async def find_targets(nodes: Sequence[str], timeout_s: float, interfaces: Sequence[str] | None) -> list[Target]:
    """The explicit ``--node`` targets if any, else the nodes zeroconf finds within ``timeout_s``."""
    if nodes:
        return [parse_node(n) for n in nodes]
    from common.discovery import browse_nodes  # zeroconf only when asked to browse

    found = await browse_nodes(timeout_s, list(interfaces) if interfaces else None)
    return [Target(n.host, n.port, n.role, n.node_id) for n in found if n.host]
