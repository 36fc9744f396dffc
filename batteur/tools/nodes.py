"""Finding nodes for the command-line tools (explicit ``HOST:PORT`` or zeroconf discovery), and what every tool
does the same way: one-line errors with their exit codes, output into a pipe that closes, Ctrl-C."""

from __future__ import annotations

import ipaddress
import os
import socket
import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import TextIO

from batteur.errors import FAILED, INTERRUPTED, USAGE, report_error
from common.config import DEFAULT_RIG
from common.output_paths import point_at_devnull
from common.transport import format_address, parse_address

INTERFACES_ENV = "BATTEUR_INTERFACES"
"""The nodes' own setting (docs/runtime.md): where this machine's (or container's) nodes run mDNS."""
INTERFACE_HELP = ("address, name or 'all' (repeatable; default: the interfaces in BATTEUR_INTERFACES, where this "
                  "machine's or container's nodes announce, if set, else loopback)")
"""What ``--interface`` says in the help of every tool that browses (``batteur ls``, ``echo``, ``send``)."""
BROWSE_S = 3.0
"""How long every tool that browses (``batteur ls``, ``echo``, ``send --to ROLE``) looks for nodes by default,
seconds (``--browse``): less than 2 can miss nodes, more so on a loaded machine."""
BROWSE_HELP = f"seconds to browse for nodes (default {BROWSE_S:g}; less than 2 can miss nodes)"
"""What ``--browse`` says in the help of every tool that browses."""
RIG_ENV = "BATTEUR_RIG"
"""The nodes' own setting (docs/runtime.md): the rig they belong to; the tools find the nodes of one rig."""
RIG_HELP = (f"the rig whose nodes to find (default: BATTEUR_RIG if set, else {DEFAULT_RIG}, a node's own default); "
            "nodes of another rig (another class on the network) are left out, as the nodes themselves ignore them")
"""What ``--rig`` says in the help of every tool that browses."""


def browse_interfaces(given: Sequence[str]) -> tuple[list[str], str]:
    """The interfaces a tool browses on and where they come from (for messages): ``--interface``, else
    BATTEUR_INTERFACES (comma-separated), else none (loopback)."""
    if given:
        return list(given), "--interface"
    from_env = [part.strip() for part in os.environ.get(INTERFACES_ENV, "").split(",") if part.strip()]
    if from_env:
        return from_env, INTERFACES_ENV
    return [], ""


def where_browsed(interfaces: Sequence[str], source: str) -> str:
    """Where a tool browsed, for its "nothing found" message."""
    if interfaces:
        return f"on {', '.join(interfaces)} ({source})"
    return "on loopback (--interface eth0, say, for the nodes of a LAN or a compose network)"


@dataclass(frozen=True)
class Target:
    """A node to talk to."""

    host: str
    """As given or discovered ('' when the node announced no address this machine can use)."""
    port: int
    role: str = "?"
    node_id: str = ""
    ip: str = ""
    """Numeric address the tool sends to ('' when unreachable)."""
    announced: tuple[str, ...] = ()
    """Every address the node announced (discovered nodes)."""
    rig: str = ""
    """The rig the node announced ('' for a node given as ``HOST:PORT``: not known)."""

    @property
    def address(self) -> str:
        return format_address(self.host, self.port) if self.host else f"?:{self.port}"

    @property
    def socket_address(self) -> str:
        """``ip:port`` as the transport names the source of a datagram."""
        return format_address(self.ip, self.port)


class OutputClosed(Exception):
    """The reader of our standard output has gone (``batteur echo ... | head``)."""


def write_line(text: str, stream: TextIO | None = None) -> None:
    """Print one line now; raise :class:`OutputClosed` once the reader has gone."""
    out = stream if stream is not None else sys.stdout
    try:
        out.write(text + "\n")
        out.flush()
    except (BrokenPipeError, ValueError) as exc:  # ValueError: the stream was closed
        point_at_devnull(out)
        raise OutputClosed from exc


def run_tool(prog: str, run: Callable[[], int]) -> int:
    """Run a tool's body: bad input is one line and exit 2, a network failure one line and exit 1, Ctrl-C exit
    130, a reader that went away a quiet stop; never a traceback."""
    try:
        return run()
    except OutputClosed:
        return 0
    except ValueError as exc:
        return report_error(prog, exc, USAGE)
    except OSError as exc:  # a socket that cannot be opened, mDNS that cannot start
        return report_error(prog, exc, FAILED)
    except KeyboardInterrupt:
        print(f"\n{prog}: interrupted", file=sys.stderr)
        return INTERRUPTED
    except Exception as exc:
        # a bad --interface; common.discovery (zeroconf) is imported only by the tools that browse
        discovery = sys.modules.get("common.discovery")
        if discovery is None or not isinstance(exc, discovery.DiscoveryError):
            raise
        return report_error(prog, exc, USAGE)


def bind_address(targets: Sequence[Target]) -> str:
    """Where a tool should listen to hear answers from ``targets``: loopback unless one is elsewhere, and an
    IPv6 socket when one is IPv6 (an IPv4 socket cannot reach ``[::1]``)."""
    ips = [ipaddress.ip_address(t.ip.split("%", 1)[0]) for t in targets if t.ip]
    v6 = any(ip.version == 6 for ip in ips)
    if all(ip.is_loopback for ip in ips):
        if not v6:
            return "127.0.0.1"
        if all(ip.version == 6 for ip in ips):
            return "::1"
    return "::" if v6 else "0.0.0.0"


def target_networks(targets: Sequence[Target]) -> list[str]:
    """Allow-list of a tool's socket: only the targets themselves may answer."""
    networks: list[str] = []
    for target in targets:
        if target.ip:
            ip = ipaddress.ip_address(target.ip.split("%", 1)[0])
            networks.append(f"{ip}/{ip.max_prefixlen}")
    return networks


def resolve_host(host: str) -> str:
    """The numeric address of ``host`` (IPv4 first); ValueError naming the host when it does not resolve."""
    try:
        ipaddress.ip_address(host.split("%", 1)[0])
        return host  # already numeric (an IPv6 scope kept)
    except ValueError:
        pass
    try:
        infos = socket.getaddrinfo(host, None, socket.AF_UNSPEC, socket.SOCK_DGRAM)
    except (OSError, UnicodeError) as exc:
        raise ValueError(f"cannot resolve host {host!r}: {getattr(exc, 'strerror', None) or exc}") from None
    infos.sort(key=lambda info: info[0] != socket.AF_INET)
    return str(infos[0][4][0])


def parse_node(spec: str) -> Target:
    """``HOST:PORT`` (or ``[v6]:PORT``) as a target, its host resolved; raises ValueError."""
    try:
        host, port = parse_address(spec.strip())
    except ValueError as exc:
        example = "" if "e.g." in str(exc) else " (e.g. 127.0.0.1:9000 or [::1]:9000)"
        raise ValueError(f"--node {exc}{example}") from None
    try:
        return Target(host, port, ip=resolve_host(host))
    except ValueError as exc:
        raise ValueError(f"--node {spec}: {exc}") from None


def unique(targets: Sequence[Target]) -> list[Target]:
    """Targets without repeats (the same socket address given twice)."""
    seen: set[tuple[str, int]] = set()
    out: list[Target] = []
    for target in targets:
        key = (target.ip or target.host or target.node_id, target.port)
        if key not in seen:
            seen.add(key)
            out.append(target)
    return out


async def browse_targets(timeout_s: float, interfaces: Sequence[str] | None) -> list[Target]:
    """The nodes zeroconf finds within ``timeout_s`` seconds on ``interfaces`` (none: loopback), each record as a
    target (a node without a usable address kept, with ``ip`` empty, so the tools can say so; repeats kept)."""
    from common.discovery import browse_nodes  # zeroconf only when asked to browse

    found = await browse_nodes(timeout_s, list(interfaces) if interfaces else None)
    targets = [Target(n.host, n.port, n.role, n.node_id, announced=n.addresses, rig=n.rig) for n in found]
    return [replace(t, ip=t.host) if t.host else t for t in targets]


async def find_targets(nodes: Sequence[str], timeout_s: float, interfaces: Sequence[str] | None) -> list[Target]:
    """The explicit ``--node`` targets if any, else the nodes zeroconf finds within ``timeout_s``
    (:func:`browse_targets`), without repeats."""
    if nodes:
        return unique([parse_node(n) for n in nodes])
    return unique(await browse_targets(timeout_s, interfaces))


def chosen_rig(given: str | None, environ: Mapping[str, str] | None = None) -> str:
    """The rig a tool looks for: ``--rig`` (``given``), else ``BATTEUR_RIG`` of ``environ`` (None: the tool's), else
    the default rig name, as a node started in the same shell would pick."""
    env = os.environ if environ is None else environ
    return given or env.get(RIG_ENV) or DEFAULT_RIG


def of_rig(targets: Sequence[Target], rig: str) -> tuple[list[Target], list[Target]]:
    """``targets`` split into those of ``rig`` (and those given as ``HOST:PORT``, of no known rig) and the others:
    until 8 Dec ``ls`` listed, and ``send --to ROLE`` started, another class's nodes on the same network."""
    kept = [t for t in targets if t.rig in ("", rig)]
    return kept, [t for t in targets if t.rig not in ("", rig)]


def left_out_text(others: Sequence[Target], rig: str) -> str:
    """What the tools say of the nodes of other rigs they left out ('' when none)."""
    if not others:
        return ""
    rigs = ", ".join(sorted({t.rig for t in others}))
    return (f"{len(others)} node(s) of other rigs ({rigs}) left out: this is rig {rig} "
            f"(--rig NAME or {RIG_ENV} to look at another)")
