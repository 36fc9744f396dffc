"""OSCQuery: each node serves its OSC namespace over HTTP (JSON) and streams value changes over WebSocket.

The namespace is generated from the message models (:mod:`common.messages`): one leaf per
address, with the attributes of the OSCQuery proposal (https://github.com/Vidvox/OSCQueryProposal):

``FULL_PATH``
    The OSC address.
``CONTENTS``
    Children of a container (``/batteur``, ``/batteur/sound``, ...).
``TYPE``
    OSC type tags: ``i``, ``f``, ``s``; a rig time is ``if`` (whole seconds, fraction). A
    variadic last field (e.g. resonance gains) is not part of TYPE (OSCQuery cannot express
    it); its DESCRIPTION says so.
``RANGE``
    One entry per type tag: ``{"MIN": .., "MAX": ..}``, ``{"VALS": [..]}`` for choices, or null.
``ACCESS``
    3 (read and write) for the control messages this node's role accepts, 1 (read only) for
    everything else it sends or receives.
``VALUE``
    The arguments of the last message seen at that address (sent or received by this node);
    absent until one was seen.
``DESCRIPTION``
    The model's docstring, then each argument with its unit.
``HOST_INFO`` (``GET /?HOST_INFO``)
    Node name, OSC address and transport, WebSocket address, supported extensions.

``GET /path?ATTRIBUTE`` returns ``{"ATTRIBUTE": value}``; an unknown path is 404, an attribute
that path does not have 204. A WebSocket on the same port takes JSON commands
``{"COMMAND": "LISTEN", "DATA": "/batteur/sound/level"}`` (and ``IGNORE``) and then receives
every new value of that address as a binary OSC packet; binary frames sent by the client are
OSC packets handed to the node as if they had come over UDP (same allow-list, size and rate
checks, same validation).

The server is advertised as ``_oscjson._tcp`` through :meth:`common.discovery.Discovery.register_extra`
(see :class:`common.runtime.Node`).
"""

from __future__ import annotations

import asyncio
import ipaddress
import json
import logging
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any
from urllib.parse import unquote, urlsplit

from websockets.asyncio.server import Server, ServerConnection, serve
from websockets.exceptions import ConnectionClosed
from websockets.http11 import Request, Response

from common.messages import REGISTRY, Family, MessageRegistry, OscMessage, WireKind, parse_packet
from common.messages.base import MessageError

log = logging.getLogger("batteur.oscquery")
_connection_log = logging.getLogger("batteur.oscquery.connections")
"""websockets logs two INFO lines per HTTP request and per WebSocket: a client polling the namespace would flood
the node's log; warnings and errors still show."""
_connection_log.setLevel(logging.WARNING)

SERVICE_TYPE = "_oscjson._tcp.local."
"""DNS-SD type of an OSCQuery server."""

ACCESS_NONE, ACCESS_READ, ACCESS_WRITE, ACCESS_READ_WRITE = 0, 1, 2, 3

COMMON_PREFIXES = ("/batteur/hello", "/batteur/health", "/batteur/clock/", "/batteur/subscribe")
ROLE_NAMESPACES: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    # role: (prefixes of the controls it accepts, prefixes of the other messages it sends or receives)
    "physics": (("/batteur/physics/", "/batteur/score/"), ("/batteur/contact", "/batteur/pose", "/batteur/skeleton",
                                                          "/batteur/graphics/score_position")),
    "interaction": (("/batteur/interaction/",), ("/batteur/contact", "/batteur/impact", "/batteur/damping")),
    "sound": (("/batteur/sound/",), ("/batteur/impact", "/batteur/damping")),
    "graphics": (("/batteur/graphics/",), ("/batteur/pose", "/batteur/skeleton", "/batteur/impact",
                                           "/batteur/damping")),
}
"""What each role's namespace holds. A role not listed serves every registered message, all writable."""

MAX_CONNECTIONS = 32
MAX_LISTENS = 256
QUEUE_LIMIT = 256


def _starts(address: str, prefixes: Iterable[str]) -> bool:
    """Whether ``address`` is under one of ``prefixes`` (``/a/``: anything below; ``/a``: it or below)."""
    return any(address.startswith(p) if p.endswith("/") else address == p or address.startswith(p + "/")
               for p in prefixes)


def namespace_models(role: str, registry: MessageRegistry = REGISTRY) -> dict[str, tuple[type[OscMessage], int]]:
    """The messages in ``role``'s namespace: address -> (model, ACCESS)."""
    spec = ROLE_NAMESPACES.get(role)
    out: dict[str, tuple[type[OscMessage], int]] = {}
    for model in registry:
        address = model.ADDRESS
        if spec is None:
            out[address] = (model, ACCESS_READ_WRITE)
            continue
        controls, others = spec
        if _starts(address, controls) and model.FAMILY is Family.CONTROL:
            out[address] = (model, ACCESS_READ_WRITE)
        elif _starts(address, controls) or _starts(address, others) or _starts(address, COMMON_PREFIXES):
            out[address] = (model, ACCESS_READ)
    return out


def _num(value: float) -> int | float:
    return int(value) if float(value).is_integer() and abs(value) < 2**53 else value


def leaf(model: type[OscMessage], access: int) -> dict[str, Any]:
    """The OSCQuery node of one message (without VALUE)."""
    tags = ""
    ranges: list[Any] = []
    lines = []
    tail = ""
    for f in model.wire_fields():
        if f.variadic:
            tail = f"then any number of {f.kind.name.lower()} arguments: {f.name} ({f.description})"
            continue
        if f.kind is WireKind.TIME:
            tags += "if"
            ranges += [None, {"MIN": 0.0, "MAX": 1.0}]
            lines.append(f"{f.name} (i + f): {f.description}")
            continue
        tags += f.kind.value
        if f.choices is not None:
            ranges.append({"VALS": [int(c) if f.kind is WireKind.INT else c for c in f.choices]})
        elif f.minimum is not None or f.maximum is not None:
            r: dict[str, int | float] = {}
            if f.minimum is not None:
                r["MIN"] = _num(f.minimum)
            if f.maximum is not None:
                r["MAX"] = _num(f.maximum)
            ranges.append(r)
        else:
            ranges.append(None)
        lines.append(f"{f.name} ({f.kind.value}): {f.description}")
    if tail:
        lines.append(tail)
    doc = " ".join((model.__doc__ or model.__name__).split())
    node: dict[str, Any] = {
        "FULL_PATH": model.ADDRESS,
        "TYPE": tags,
        "ACCESS": access,
        "DESCRIPTION": doc + (" Arguments: " + "; ".join(lines) + "." if lines else ""),
    }
    if tags:
        node["RANGE"] = ranges
    return node


def build_tree(models: dict[str, tuple[type[OscMessage], int]], description: str = "") -> dict[str, Any]:
    """The whole namespace as nested OSCQuery nodes (root ``/``)."""
    root: dict[str, Any] = {"FULL_PATH": "/", "ACCESS": ACCESS_NONE, "CONTENTS": {}}
    if description:
        root["DESCRIPTION"] = description
    for address, (model, access) in sorted(models.items()):
        parts = address.strip("/").split("/")
        node = root
        for depth, part in enumerate(parts):
            contents = node.setdefault("CONTENTS", {})
            path = "/" + "/".join(parts[: depth + 1])
            child = contents.get(part)
            if depth == len(parts) - 1:
                # a message address that is also a container (/batteur/impact and /batteur/impact/end)
                merged = leaf(model, access)
                if child is not None and "CONTENTS" in child:
                    merged["CONTENTS"] = child["CONTENTS"]
                contents[part] = merged
                node = merged
            else:
                if child is None:
                    child = {"FULL_PATH": path, "ACCESS": ACCESS_NONE, "CONTENTS": {}}
                    contents[part] = child
                child.setdefault("CONTENTS", {})
                node = child
    return root


def find(tree: dict[str, Any], path: str) -> dict[str, Any] | None:
    """The node at ``path`` (``/`` is the root), or None."""
    node = tree
    for part in [p for p in path.split("/") if p]:
        contents = node.get("CONTENTS")
        if not isinstance(contents, dict) or part not in contents:
            return None
        node = contents[part]
    return node


@dataclass(eq=False)
class _Client:
    connection: ServerConnection
    listening: set[str] = field(default_factory=set)
    queue: asyncio.Queue[bytes] = field(default_factory=lambda: asyncio.Queue(QUEUE_LIMIT))
    dropped: int = 0


class OscQueryServer:
    """HTTP + WebSocket OSCQuery server of one node.

    Parameters
    ----------
    name : str
        Node name for HOST_INFO (the node id).
    role : str
        Picks the namespace (:data:`ROLE_NAMESPACES`).
    osc_host, osc_port : str, int
        Where the node receives OSC over UDP (HOST_INFO).
    receive : callable(data, host, port) or None
        Hands an OSC packet received over the WebSocket to the node (with its checks).
    allow : sequence of ip networks or None
        Clients allowed to connect; None: anyone who can reach the socket.
    registry : MessageRegistry
        Where the models come from.
    """

    def __init__(
        self,
        name: str,
        role: str,
        osc_host: str,
        osc_port: int,
        receive: Callable[[bytes, str, int], None] | None = None,
        allow: Sequence[ipaddress.IPv4Network | ipaddress.IPv6Network] | None = None,
        registry: MessageRegistry = REGISTRY,
    ) -> None:
        self.name = name
        self.role = role
        self.osc_host = osc_host
        self.osc_port = osc_port
        self.receive = receive
        self.allow = list(allow) if allow is not None else None
        self.models = namespace_models(role, registry)
        self.tree = build_tree(self.models, f"Batteur {role} node {name}")
        self.values: dict[str, Callable[[], bytes]] = {}
        self.clients: set[_Client] = set()
        self.listeners: dict[str, set[_Client]] = {}
        self.refused = 0
        """connections refused: not allowed, or too many"""
        self.http_requests = 0
        self.host = ""
        self.port = 0
        self._server: Server | None = None
        self._writers: set[asyncio.Task[None]] = set()

    # ------------------------------------------------------------------ lifecycle

    async def start(self, host: str = "127.0.0.1", port: int = 0) -> None:
        """Listen for HTTP and WebSocket clients on ``host:port`` (0: any free port)."""
        self._server = await serve(
            self._session, host, port, process_request=self._process_request, max_size=65536,
            ping_interval=None, server_header="batteur-oscquery", logger=_connection_log,
        )
        sock = next(iter(self._server.sockets))
        self.host, self.port = host, int(sock.getsockname()[1])
        log.info("OSCQuery on http://%s:%d/ (%d addresses)", host, self.port, len(self.models))

    async def stop(self) -> None:
        if self._server is not None:
            self._server.close()
            await self._server.wait_closed()
            self._server = None
        for task in self._writers:
            task.cancel()
        await asyncio.gather(*self._writers, return_exceptions=True)
        self._writers.clear()

    def txt(self) -> dict[str, str]:
        """TXT properties for the ``_oscjson._tcp`` record."""
        return {"role": self.role, "node_id": self.name, "osc_port": str(self.osc_port)}

    # ------------------------------------------------------------------ values

    def observe(self, address: str, packet: Callable[[], bytes]) -> None:
        """A message went through the node: remember it as the address's VALUE, stream it to listeners."""
        if address not in self.models:
            return
        self.values[address] = packet
        clients = self.listeners.get(address)
        if not clients:
            return
        data = packet()
        for client in clients:
            try:
                client.queue.put_nowait(data)
            except asyncio.QueueFull:
                client.dropped += 1

    def value(self, address: str) -> list[Any] | None:
        """The last arguments seen at ``address`` (None if none yet)."""
        packet = self.values.get(address)
        if packet is None:
            return None
        try:
            raws = parse_packet(packet())
        except MessageError:
            return None
        return list(raws[0].args) if raws else None

    def host_info(self) -> dict[str, Any]:
        return {
            "NAME": self.name,
            "OSC_IP": self.osc_host,
            "OSC_PORT": self.osc_port,
            "OSC_TRANSPORT": "UDP",
            "WS_IP": self.host,
            "WS_PORT": self.port,
            "EXTENSIONS": {
                "ACCESS": True, "VALUE": True, "RANGE": True, "DESCRIPTION": True, "LISTEN": True,
                "TAGS": False, "EXTENDED_TYPE": False, "UNIT": False, "CRITICAL": False, "CLIPMODE": False,
                "OVERLOADS": False, "PATH_CHANGED": False, "PATH_ADDED": False, "PATH_REMOVED": False,
                "PATH_RENAMED": False, "HTML": False,
            },
        }

    def with_values(self, node: dict[str, Any]) -> dict[str, Any]:
        """A copy of ``node`` with VALUE filled in wherever a value is known."""
        out = dict(node)
        path = node.get("FULL_PATH", "")
        if "TYPE" in node:
            value = self.value(path)
            if value is not None:
                out["VALUE"] = value
        if "CONTENTS" in node:
            out["CONTENTS"] = {k: self.with_values(v) for k, v in node["CONTENTS"].items()}
        return out

    def answer(self, target: str) -> tuple[int, Any]:
        """HTTP status and JSON body for a request target (``/path?ATTRIBUTE``)."""
        parts = urlsplit(target)
        path = unquote(parts.path) or "/"
        query = unquote(parts.query).split("&")[0] if parts.query else ""
        if query == "HOST_INFO":
            return 200, self.host_info()
        node = find(self.tree, path)
        if node is None:
            return 404, {"error": f"no such path {path}"}
        full = self.with_values(node)
        if query:
            if query not in full:
                return 204, None
            return 200, {query: full[query]}
        return 200, full

    # ------------------------------------------------------------------ HTTP and WebSocket

    def _allowed(self, connection: ServerConnection) -> bool:
        if self.allow is None:
            return True
        try:
            ip = ipaddress.ip_address(str(connection.remote_address[0]).split("%")[0])
        except (ValueError, TypeError, IndexError):
            return False
        if isinstance(ip, ipaddress.IPv6Address) and ip.ipv4_mapped is not None:
            ip = ip.ipv4_mapped
        return any(ip in net for net in self.allow if net.version == ip.version)

    def _process_request(self, connection: ServerConnection, request: Request) -> Response | None:
        if not self._allowed(connection) or len(self.clients) >= MAX_CONNECTIONS:
            self.refused += 1
            return connection.respond(403, "forbidden\n")
        if request.headers.get("Upgrade", "").lower() == "websocket":
            return None
        self.http_requests += 1
        status, body = self.answer(request.path)
        if status == 204:
            response = connection.respond(204, "")
            return Response(204, "No Content", response.headers, b"")
        text = json.dumps(body, indent=None, separators=(",", ":")) + "\n"
        response = connection.respond(status, text)
        del response.headers["Content-Type"]
        response.headers["Content-Type"] = "application/json"
        return response

    async def _session(self, connection: ServerConnection) -> None:
        client = _Client(connection)
        self.clients.add(client)
        writer = asyncio.create_task(self._write(client))
        self._writers.add(writer)
        try:
            async for frame in connection:
                if isinstance(frame, bytes):
                    if self.receive is not None:
                        host, port = connection.remote_address[:2]
                        self.receive(frame, str(host), int(port))
                    continue
                self._command(client, frame)
        except ConnectionClosed:
            pass
        finally:
            writer.cancel()
            self._writers.discard(writer)
            self.clients.discard(client)
            for address in client.listening:
                self.listeners.get(address, set()).discard(client)

    def _command(self, client: _Client, text: str) -> None:
        try:
            command = json.loads(text)
        except ValueError:
            return
        if not isinstance(command, dict):
            return
        what, path = command.get("COMMAND"), command.get("DATA")
        if not isinstance(path, str) or path not in self.models:
            return
        if what == "LISTEN" and len(client.listening) < MAX_LISTENS:
            client.listening.add(path)
            self.listeners.setdefault(path, set()).add(client)
        elif what == "IGNORE":
            client.listening.discard(path)
            self.listeners.get(path, set()).discard(client)

    async def _write(self, client: _Client) -> None:
        try:
            while True:
                data = await client.queue.get()
                await client.connection.send(data)
        except ConnectionClosed:
            pass
