"""Finding nodes for the command-line tools: explicit ``HOST:PORT`` or zeroconf discovery."""

from __future__ import annotations

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
