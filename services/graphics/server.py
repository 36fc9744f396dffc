"""The view server: the page over HTTP and the frame stream over a WebSocket, on one port.

Built on the ``websockets`` library: ``process_request`` answers plain HTTP
requests (the page, its script, ``/api/*``) and lets ``/ws`` upgrade to a
WebSocket. Every page gets a welcome (kit, skeleton, view settings) and then
whatever the core produces (frames, status, settings). Slow pages skip frames
(while more than ``MAX_BACKLOG`` bytes wait for them) instead of slowing the node
or piling up memory.

Only same-origin pages (or clients that send no ``Origin``) may open the
WebSocket, so a page from another site cannot drive the editor.

Page -> node messages (JSON): ``save_kit`` (validated with ``common.kit``,
written only into the configured kit directory), ``poser_on``/``poser``/
``poser_off`` (the pose editor on physics' 57-DOF body: ``poser`` carries
``{joint: [x, y, z] degrees}`` and ``drive``; with ``drive`` the node sends the
posture to physics, /batteur/physics/posture), ``save_pose`` (a key pose into
``poses.yaml``, :mod:`common.gesture.keyposes`), ``hardware`` (a kit the page
edits, not saved: the reply carries its beaters and stands, ``common.kit.kit_hardware``,
so the page draws them as physics would build them), ``preview_rate`` (``rate``) and
``preview_bars`` (``first``, ``last``; 0 0: the whole score): the score preview's speed and bar range, as
``/batteur/graphics/preview_rate`` and ``/batteur/graphics/preview_bars`` set them (refused: a ``refused``
reply naming the control and why, with the node's view). Bad messages get an error reply and are counted; they
never stop the server.
"""

from __future__ import annotations

import ipaddress
import json
import logging
import mimetypes
import re
from collections.abc import Callable
from http import HTTPStatus
from pathlib import Path
from typing import Any
from urllib.parse import urlparse

import numpy as np
from pydantic import ValidationError
from websockets.asyncio.server import Server, ServerConnection, broadcast, serve
from websockets.datastructures import Headers
from websockets.exceptions import ConnectionClosed
from websockets.http11 import Request, Response

from common.gesture.keyposes import POSE_NAME, KeyPoses
from common.kit import Kit, load_kit, save_kit
from common.messages.graphics import GraphicsPreviewBars
from services.graphics.core import GraphicsCore
from services.graphics.poser import CharacterPoser, is_character, rest_poser
from services.graphics.scene import hardware_json

log = logging.getLogger("batteur.graphics")

STATIC_DIR = Path(__file__).parent / "static"
FILE_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,80}\.(yaml|yml|json)$")
MAX_PAGE_MESSAGE = 256 * 1024  # bytes
CLOSE_TIMEOUT_S = 1.0
"""How long closing waits for a page to answer (a frozen tab would hold Ctrl-C up 10 s by default)."""
MAX_BACKLOG = 64 * 1024
"""Bytes waiting to be sent to a page above which it skips frames (about half a second of frames)."""
EDITOR_MODES = ("local", "all", "off")
"""``--editor``: which pages may use the kit and pose editor: pages opened on this machine, every page, none."""
EDITOR_MESSAGES = frozenset({"poser_on", "poser", "poser_off", "save_kit", "save_pose"})
"""Page messages of the editor: they drive physics' drummer (``poser`` with ``drive``) or write files."""
FORWARDING_HEADERS = ("X-Forwarded-For", "Forwarded", "X-Real-IP")
"""Headers a reverse proxy adds naming the browser it forwards for: a request with one is not local (``--editor``)."""
EDITOR_OFF = {"off": "the editor is off on this node (graphics --editor off)",
              "local": "the editor is for pages opened on the machine the graphics node runs on; this page shows the "
                       "view only (graphics --editor all opens it to every machine that reaches the page)"}
"""Why a page may not use the editor, by ``--editor`` (also the page's tooltip where its editor button was)."""
SAVING_OFF = ("saving is disabled: start the graphics node with --kit-dir DIR "
              "(under batteur rig: its --kit-dir DIR)")
"""Why a save is refused without a kit directory, and what to do: also the page's tooltip on its save buttons."""


def assets_missing(static_dir: Path = STATIC_DIR) -> list[str]:
    """Built files the page needs that are not there (run ``batteur graphics build``)."""
    return [name for name in ("index.html", "app.js", "style.css") if not (static_dir / name).is_file()]


class ViewServer:
    """Serves the page and streams the core's page messages to every connected page."""

    def __init__(self, core: GraphicsCore, static_dir: Path = STATIC_DIR, kit_dir: Path | None = None,
                 clock: Callable[[], float] | None = None, editor: str = "local") -> None:
        if editor not in EDITOR_MODES:
            raise ValueError(f"editor {editor!r}: one of {', '.join(EDITOR_MODES)}")
        self.core = core
        self.editor = editor
        """``--editor``: local (pages opened on this machine), all, or off. A view served to the class's network
        (``--host 0.0.0.0``) gave every student's browser the pose editor, which drives the drummer."""
        self.own_addresses: frozenset[str] = frozenset()
        """This machine's addresses (read at :meth:`start`): a page from one of them is local."""
        self.static_dir = static_dir
        self.kit_dir = kit_dir.resolve() if kit_dir is not None else None
        self.clock = clock or (lambda: 0.0)
        self.clients: set[ServerConnection] = set()
        self.server: Server | None = None
        self.port = 0
        self.poser: CharacterPoser | None = None
        self.editors: set[object] = set()
        """The pages with the editor open: the body is released when the last one closes it or goes."""
        self.poser_angles: np.ndarray | None = None
        """The edited joint angles (57,) radians."""
        self.poser_body = "rest"
        """Which body the editor poses: "live" (physics' newest pose) or "rest" (the shipped snapshot)."""
        self.counters = {"http": 0, "not_found": 0, "ws_connects": 0, "page_errors": 0, "sent": 0, "foreign_origin": 0,
                         "skipped_frames": 0, "saves_refused": 0, "edits_refused": 0}
        core.page_sink = self.broadcast

    # --- lifecycle ----------------------------------------------------------------------------
    async def start(self, host: str, port: int) -> int:
        """Listen on ``host:port`` (0: any free port); returns the port."""
        logging.getLogger("websockets.server").setLevel(logging.WARNING)
        self.own_addresses = own_addresses()
        self.server = await serve(self._ws_handler, host, port, process_request=self._http,
                                  max_size=MAX_PAGE_MESSAGE, compression=None, ping_interval=5, ping_timeout=10,
                                  close_timeout=CLOSE_TIMEOUT_S)
        sock = next(iter(self.server.sockets))
        self.port = int(sock.getsockname()[1])
        missing = assets_missing(self.static_dir)
        if missing:
            log.error("the page is not built (%s missing): run `batteur graphics build`", ", ".join(missing))
        log.info("graphics view on http://%s:%d/", host if ":" not in host else f"[{host}]", self.port)
        return self.port

    async def serve_forever(self) -> None:
        if self.server is None:
            raise RuntimeError("start() first")
        try:
            await self.server.serve_forever()
        finally:
            await self.close()

    async def close(self) -> None:
        if self.server is not None:
            self.server.close()
            await self.server.wait_closed()
            self.server = None

    # --- HTTP ---------------------------------------------------------------------------------
    def _http(self, connection: ServerConnection, request: Request) -> Response | None:
        path = request.path.split("?", 1)[0]
        if path == "/ws":
            origin = request.headers.get("Origin")
            if origin is not None and urlparse(origin).netloc != request.headers.get("Host"):
                # a page from another site must not drive this node (the editor writes files)
                self.counters["foreign_origin"] += 1
                return _response(HTTPStatus.FORBIDDEN, b"cross-origin WebSocket refused\n", "text/plain")
            return None
        self.counters["http"] += 1
        if path == "/api/status":
            return _json_response({**self.core.status(self.clock()), "server": dict(self.counters)})
        if path == "/api/kit":
            return _json_response(self.core.kit.model_dump(mode="json"))
        if path == "/healthz":
            return _response(HTTPStatus.OK, b"ok\n", "text/plain")
        name = "index.html" if path in ("/", "/index.html") else path.lstrip("/")
        if "/" in name or name.startswith(".") or not (self.static_dir / name).is_file():
            self.counters["not_found"] += 1
            if name == "index.html":
                return _response(HTTPStatus.SERVICE_UNAVAILABLE,
                                 b"the page is not built: run `batteur graphics build`\n", "text/plain")
            return _response(HTTPStatus.NOT_FOUND, b"not found\n", "text/plain")
        body = (self.static_dir / name).read_bytes()
        ctype = mimetypes.guess_type(name)[0] or "application/octet-stream"
        if ctype.startswith("text/") or ctype.endswith("javascript"):
            ctype += "; charset=utf-8"
        return _response(HTTPStatus.OK, body, ctype)

    # --- WebSocket ----------------------------------------------------------------------------
    async def _ws_handler(self, connection: ServerConnection) -> None:
        self.counters["ws_connects"] += 1
        self.clients.add(connection)
        try:
            # a page through a reverse proxy on this machine comes from loopback but is not local (a student's
            # browser): the proxy says so in one of these headers (an SSH tunnel adds none: it counts as local)
            headers = connection.request.headers if connection.request is not None else {}
            proxied = any(name in headers for name in FORWARDING_HEADERS)
            may_edit = self.may_edit(connection.remote_address[0] if connection.remote_address else "", proxied)
            for message in [*self.core.welcome(), self.saving_json(), self.editor_json(may_edit)]:
                await connection.send(json.dumps(message))
            async for raw in connection:
                reply = self.handle_page_message(raw, connection, may_edit)
                if reply is not None:
                    await connection.send(json.dumps(reply))
        except ConnectionClosed:
            pass
        finally:
            self.clients.discard(connection)
            self.editors.discard(connection)
            if (not self.clients or not self.editors) and self.poser is not None:
                self._poser_off()

    def broadcast(self, messages: list[dict[str, Any]]) -> None:
        """Send ``messages`` to every page (called from the core's step, on the event loop).

        ``websockets.broadcast`` has no backpressure, so a page that does not keep up (a slow link, a frozen
        tab) skips frames while more than :data:`MAX_BACKLOG` bytes wait for it; it still gets every other
        message (kit, skeleton, view, status), so it is right again as soon as it reads.
        """
        if not self.clients:
            return
        for message in messages:
            targets = self.clients
            if message.get("type") == "frame":
                targets = {c for c in self.clients if _backlog(c) <= MAX_BACKLOG}
                self.counters["skipped_frames"] += len(self.clients) - len(targets)
            broadcast(targets, json.dumps(message, separators=(",", ":")))
            self.counters["sent"] += 1

    def saving_json(self) -> dict[str, Any]:
        """Whether the page's save buttons can work (sent at connect; a page that does not know it ignores it)."""
        return {"type": "saving", "enabled": self.kit_dir is not None,
                "reason": None if self.kit_dir is not None else SAVING_OFF}

    def may_edit(self, host: str, proxied: bool = False) -> bool:
        """Whether a page from ``host`` (the connection's remote address) may use the editor (:attr:`editor`);
        ``proxied``: the request came through a proxy (:data:`FORWARDING_HEADERS`), so ``host`` is not the page's."""
        if self.editor != "local":
            return self.editor == "all"
        return not proxied and is_local(host, self.own_addresses)

    def editor_json(self, may_edit: bool) -> dict[str, Any]:
        """Whether this page may use the editor (sent at connect; the page hides its editor button if not)."""
        return {"type": "editor", "enabled": may_edit, "reason": None if may_edit else EDITOR_OFF[self.editor]}

    def handle_page_message(self, raw: str | bytes, page: object = None,
                            may_edit: bool = True) -> dict[str, Any] | None:
        """One message from ``page`` (its connection; ``may_edit``: whether it may use the editor, :meth:`may_edit`);
        returns the reply (or None). Never raises."""
        try:
            msg = json.loads(raw)
            if not isinstance(msg, dict) or not isinstance(msg.get("type"), str):
                raise ValueError("a message is a JSON object with a 'type'")
            kind = msg["type"]
            if kind in EDITOR_MESSAGES and not may_edit:  # a view-only page: refused and counted; logged once
                self.counters["edits_refused"] += 1
                if self.counters["edits_refused"] == 1:
                    log.info("editor message from a view-only page refused: %s", EDITOR_OFF[self.editor])
                if kind in ("poser", "poser_off"):  # a slider's stream, and closing: nothing to answer
                    return None
                return {"type": "saved", "ok": False, "error": EDITOR_OFF[self.editor]}
            if kind in ("save_kit", "save_pose") and self.kit_dir is None:
                # the node's setup, not a malformed message (the page disables its buttons when told at connect)
                self.counters["saves_refused"] += 1
                log.info("save refused from a page: %s", SAVING_OFF)
                return {"type": "saved", "ok": False, "error": SAVING_OFF}
            if kind == "save_kit":
                return self._save_kit(msg)
            if kind == "poser_on":
                self.editors.add(page)
                return self._poser_on()
            if kind == "poser":
                poser = self.poser or self._start_poser()
                q = poser.angles_from(msg.get("angles", {}), self.poser_angles)
                self.poser_angles = q
                self.core.show_pose(poser.names, poser.pose(q))
                if msg.get("drive", False) is True:
                    self.core.request_posture(q)
                return None
            if kind == "poser_off":  # another page still editing keeps the body
                self.editors.discard(page)
                if not self.editors:
                    self._poser_off()
                return None
            if kind == "save_pose":
                return self._save_pose(msg)
            if kind == "hardware":
                return self._hardware(msg)
            if kind in ("preview_rate", "preview_bars"):
                return self._preview_control(kind, msg)
            raise ValueError(f"unknown message type {kind!r}")
        except RecursionError:  # e.g. "[[[[..." : the JSON parser gives up, the connection must not
            self.counters["page_errors"] += 1
            log.warning("bad page message: JSON nested too deeply")
            return {"type": "saved", "ok": False, "error": "JSON nested too deeply"}
        except (ValueError, TypeError, ValidationError) as exc:
            self.counters["page_errors"] += 1
            log.warning("bad page message: %s", exc)
            return {"type": "saved", "ok": False, "error": str(exc)[:500]}
        except OSError as exc:  # the kit directory cannot be written (a file, read-only, full): the page is told
            self.counters["page_errors"] += 1
            log.warning("cannot save: %s", exc)
            return {"type": "saved", "ok": False, "error": f"cannot save: {exc}"[:500]}

    def _preview_control(self, kind: str, msg: dict[str, Any]) -> dict[str, Any] | None:
        """The page's rate select or bar boxes; every page is told by the view message. A refusal gets a reply of
        its own (``refused``, shown beside the toolbar's controls, not in the editor's save line), with the node's
        view so the page's boxes show the range (rate) that plays again; counted in ``page_errors``."""
        try:
            if kind == "preview_rate":
                self.core.set_preview_rate(msg.get("rate"), self.clock())  # type: ignore[arg-type]
            else:  # checked as /batteur/graphics/preview_bars is (MessageError: one line)
                bars = GraphicsPreviewBars.from_args([msg.get("first"), msg.get("last")])
                self.core.set_preview_bars(bars.bars, self.clock())
        except (ValueError, TypeError) as exc:
            self.counters["page_errors"] += 1
            log.warning("page %s refused: %s", kind, exc)
            return {"type": "refused", "control": kind, "error": str(exc)[:500], "view": self.core.view_json()}
        return None

    def _start_poser(self) -> CharacterPoser:
        """The editor's body: the newest live pose of physics' drummer, else the shipped rest snapshot."""
        live = self.core.live_body()
        self.poser_body = "live" if live is not None and is_character(live[0]) else "rest"
        poser = CharacterPoser(*live) if live is not None and self.poser_body == "live" else rest_poser()
        self.poser, self.poser_angles = poser, poser.angles.copy()
        return poser

    def _poser_on(self) -> dict[str, Any]:
        """Open the editor; a page joining another page's edit starts from the posture being edited."""
        if self.poser is None or self.poser_angles is None or len(self.editors) <= 1:
            self._start_poser()
        poser, angles = self.poser, self.poser_angles
        assert poser is not None and angles is not None  # set by _start_poser
        self.core.show_pose(poser.names, poser.pose(angles))
        return {"type": "poser", "body": self.poser_body, **poser.page_description(angles)}

    def _poser_off(self) -> None:
        self.core.show_pose(None, None)
        self.core.request_posture(None)
        self.poser, self.poser_angles = None, None

    def _target(self, file: object) -> Path:
        if self.kit_dir is None:
            raise ValueError(SAVING_OFF)
        if not isinstance(file, str) or not FILE_NAME.fullmatch(file):  # match's "$" lets "kit.yaml\n" through
            raise ValueError("file name: letters, digits, '_', '-', '.', ending in .yaml, .yml or .json")
        path = (self.kit_dir / file).resolve()
        if path.parent != self.kit_dir:
            raise ValueError("file must be inside the kit directory")
        return path

    def _save_kit(self, msg: dict[str, Any]) -> dict[str, Any]:
        path = self._target(msg.get("file"))
        try:
            kit = Kit.model_validate(msg.get("kit"))
        except ValidationError as exc:
            raise ValueError(f"invalid kit: {exc.errors()[0].get('msg')} at "
                             f"{'.'.join(str(p) for p in exc.errors()[0].get('loc', ()))}") from None
        if path.exists():
            _check_is_kit(path)
        self.kit_dir.mkdir(parents=True, exist_ok=True)  # type: ignore[union-attr]
        save_kit(kit, path)
        self.core.set_kit(kit)
        self.broadcast(self.core.take_page_messages())  # every page redraws the kit now
        log.info("kit saved to %s", path)
        return {"type": "saved", "ok": True, "path": str(path)}

    def _hardware(self, msg: dict[str, Any]) -> dict[str, Any]:
        """The beaters and stands of the kit the page edits (``kit``, not saved), computed here so the page draws
        the numbers physics builds with; a kit that is not valid gets an error of the same type, counted."""
        try:
            kit = Kit.model_validate(msg.get("kit"))
        except ValidationError as exc:
            self.counters["page_errors"] += 1
            error = f"invalid kit: {exc.errors()[0].get('msg')}"
            log.warning("bad page message: %s", error)
            return {"type": "hardware", "error": error[:500]}
        return {"type": "hardware", "hardware": hardware_json(kit)}

    def _save_pose(self, msg: dict[str, Any]) -> dict[str, Any]:
        """Save the edited posture (``angles`` {joint: degrees} over the editor's current ones) as a key pose."""
        path = self._target(msg.get("file", "poses.yaml"))
        name = msg.get("name")
        if not isinstance(name, str) or not POSE_NAME.fullmatch(name):
            raise ValueError("pose name: letters, digits, '_' and '.' (e.g. SNARE.left_hand.UP)")
        poser = self.poser or self._start_poser()
        q = poser.angles_from(msg.get("angles", {}), self.poser_angles)
        library = KeyPoses.load(path).with_pose(name, poser.key_pose(q))
        self.kit_dir.mkdir(parents=True, exist_ok=True)  # type: ignore[union-attr]
        library.save(path)
        return {"type": "saved", "ok": True, "path": str(path)}


def own_addresses() -> frozenset[str]:
    """Every address of this machine's interfaces (a page from one is opened on this machine)."""
    try:
        import ifaddr

        return frozenset(str(ip.ip if isinstance(ip.ip, str) else ip.ip[0]).split("%")[0]
                         for adapter in ifaddr.get_adapters() for ip in adapter.ips)
    except Exception:  # noqa: BLE001 - cannot list them: only loopback is local
        return frozenset()


def is_local(host: str, own: frozenset[str] = frozenset()) -> bool:
    """Whether ``host`` (a page's remote address) is this machine: loopback, or one of ``own`` (its addresses; a
    browser on the machine that opened its LAN address)."""
    try:
        ip = ipaddress.ip_address(host.split("%")[0])
    except ValueError:
        return False
    if isinstance(ip, ipaddress.IPv6Address) and ip.ipv4_mapped is not None:
        ip = ip.ipv4_mapped
    return ip.is_loopback or str(ip) in own


def _check_is_kit(path: Path) -> None:
    """``ValueError`` unless ``path`` holds a kit: a kit may replace a kit, never another file (poses.yaml)."""
    try:
        load_kit(path)
    except (ValueError, OSError):
        raise ValueError(f"{path.name} exists and is not a kit (the editor's poses?): "
                         "save the kit under another name") from None


def _backlog(connection: ServerConnection) -> int:
    """Bytes written to ``connection`` that the network has not taken yet."""
    return int(connection.transport.get_write_buffer_size())


def _response(status: HTTPStatus, body: bytes, content_type: str) -> Response:
    headers = Headers([("Content-Type", content_type), ("Content-Length", str(len(body))),
                       ("Cache-Control", "no-cache"), ("Connection", "close")])
    return Response(status.value, status.phrase, headers, body)


def _json_response(data: Any) -> Response:
    return _response(HTTPStatus.OK, json.dumps(data).encode(), "application/json")


async def run_forever(server: ViewServer, host: str, port: int) -> None:
    await server.start(host, port)
    await server.serve_forever()

