"""The view server without a browser: HTTP files, the WebSocket welcome and stream, the editor's saves."""

from __future__ import annotations

import asyncio
import json
import urllib.request
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any

import pytest
from websockets.asyncio.client import connect

from common.kit import load_kit
from common.messages import Skeleton
from services.graphics.core import GraphicsCore, GraphicsSettings
from services.graphics.server import ViewServer


def _run(kit_dir: Path | None, body: Callable[[ViewServer, str], Awaitable[None]], editor: str = "local") -> None:
    """Run ``body(server, "127.0.0.1:PORT")`` against a view server on a free loopback port (``editor``: its
    ``--editor``), then close it."""
    async def main() -> None:
        core = GraphicsCore(GraphicsSettings(latency=0.0, clock="rig"))
        server = ViewServer(core, kit_dir=kit_dir, editor=editor)
        port = await server.start("127.0.0.1", 0)
        try:
            await body(server, f"127.0.0.1:{port}")
        finally:
            await server.close()

    asyncio.run(main())


async def _get(url: str) -> tuple[int, str, bytes]:
    def fetch() -> tuple[int, str, bytes]:
        try:
            with urllib.request.urlopen(url, timeout=5) as response:
                return response.status, response.headers["Content-Type"], response.read()
        except urllib.error.HTTPError as err:
            return err.code, err.headers["Content-Type"], err.read()

    return await asyncio.to_thread(fetch)


async def _until(ws: Any, kind: str) -> dict[str, Any]:
    while True:
        message = json.loads(await asyncio.wait_for(ws.recv(), 5))
        if message["type"] == kind:
            return message  # type: ignore[no-any-return]


def test_http_serves_the_built_page_and_the_api() -> None:
    async def body(server: ViewServer, host: str) -> None:
        status, ctype, page = await _get(f"http://{host}/")
        assert status == 200 and ctype.startswith("text/html") and b'src="app.js"' in page
        status, ctype, script = await _get(f"http://{host}/app.js")
        assert status == 200 and "javascript" in ctype and len(script) > 100_000  # three.js is bundled in
        assert b"https://" not in script.split(b"*/", 1)[0]  # nothing fetched from a CDN
        assert (await _get(f"http://{host}/nope.js"))[0] == 404
        assert (await _get(f"http://{host}/../pyproject.toml"))[0] == 404
        status, _, kit = await _get(f"http://{host}/api/kit")
        assert status == 200 and json.loads(kit)["name"] == "default"

    _run(None, body)


def test_websocket_welcome_then_frames() -> None:
    async def body(server: ViewServer, host: str) -> None:
        async with connect(f"ws://{host}/ws") as ws:
            kit = await _until(ws, "kit")
            assert [o["id"] for o in kit["kit"]["objects"]] == [o.id for o in load_kit().objects]
            await _until(ws, "view")
            server.core.handle(Skeleton(layout=1, names=("pelvis", "head")), 0.0, "physics")
            server.core.step(0.0)
            skeleton = await _until(ws, "skeleton")
            assert skeleton["parents"] == [-1, 0]

    _run(None, body)


def test_kit_saving_is_confined_and_validated(tmp_path: Path) -> None:
    async def body(server: ViewServer, host: str) -> None:
        async with connect(f"ws://{host}/ws") as ws:
            kit = (await _until(ws, "kit"))["kit"]
            kit["objects"][1]["position"] = [-0.1, 0.4, 0.66]  # move the snare
            for bad_name in ("../escape.yaml", "kit.sh", "/etc/kit.yaml"):
                await ws.send(json.dumps({"type": "save_kit", "file": bad_name, "kit": kit}))
                reply = await _until(ws, "saved")
                assert reply["ok"] is False
            broken = json.loads(json.dumps(kit))
            broken["events"]["SNARE"]["object"] = "no_such_drum"
            await ws.send(json.dumps({"type": "save_kit", "file": "mine.yaml", "kit": broken}))
            reply = await _until(ws, "saved")
            assert reply["ok"] is False and "no_such_drum" in reply["error"]
            await ws.send(json.dumps({"type": "save_kit", "file": "mine.yaml", "kit": kit}))
            redrawn = await _until(ws, "kit")  # every page gets the saved kit, then this page the reply
            assert redrawn["kit"]["objects"][1]["position"] == [-0.1, 0.4, 0.66]
            reply = await _until(ws, "saved")
            assert reply["ok"] is True
            assert load_kit(tmp_path / "kits" / "mine.yaml").object("snare").position == (-0.1, 0.4, 0.66)
            assert server.core.kit.object("snare").position == (-0.1, 0.4, 0.66)
        assert sorted(p.name for p in (tmp_path / "kits").iterdir()) == ["mine.yaml"]
        assert not (tmp_path / "escape.yaml").exists()

    _run(tmp_path / "kits", body)


def test_saving_is_off_without_a_kit_directory() -> None:
    async def body(server: ViewServer, host: str) -> None:
        reply = server.handle_page_message(json.dumps({"type": "save_kit", "file": "a.yaml", "kit": {}}))
        assert reply is not None and reply["ok"] is False and "--kit-dir" in reply["error"]
        assert server.handle_page_message("not json")["ok"] is False  # type: ignore[index]
        assert server.handle_page_message(json.dumps({"type": "bogus"}))["ok"] is False  # type: ignore[index]
        assert server.counters["page_errors"] == 2  # the save is refused (saves_refused), not malformed

    _run(None, body)


def test_a_kit_directory_that_cannot_be_written_is_an_error_reply_not_a_crash(tmp_path: Path) -> None:
    blocked = tmp_path / "kits"
    blocked.write_text("a file where the kit directory should be")

    async def body(server: ViewServer, host: str) -> None:
        kit = load_kit().model_dump(mode="json")
        reply = server.handle_page_message(json.dumps({"type": "save_kit", "file": "mine.yaml", "kit": kit}))
        assert reply is not None and reply["ok"] is False and "cannot save" in reply["error"]
        assert server.counters["page_errors"] == 1
        async with connect(f"ws://{host}/ws") as ws:  # the server still serves pages
            assert (await _until(ws, "kit"))["kit"]["name"] == kit["name"]

    _run(blocked, body)


def test_the_served_bundle_is_built_from_the_current_sources() -> None:
    """`batteur graphics build` was run after the last change to the page (static/ is committed)."""
    import hashlib

    web = Path(__file__).resolve().parents[2] / "services" / "graphics" / "web"
    build = json.loads((web.parent / "static" / "BUILD.json").read_text())
    for name in ("app.js", "index.html", "style.css"):
        digest = hashlib.sha256((web / "src" / name).read_bytes()).hexdigest()
        assert build["sources"][name] == digest, f"static/ is stale for {name}: run `batteur graphics build`"
    package = json.loads((web / "package.json").read_text())
    assert build["three"] == package["dependencies"]["three"]


def test_a_page_from_another_origin_cannot_open_the_websocket() -> None:
    from websockets.exceptions import InvalidStatus

    async def body(server: ViewServer, host: str) -> None:
        with pytest.raises(InvalidStatus):
            async with connect(f"ws://{host}/ws", origin="http://evil.example"):  # type: ignore[arg-type]
                pass
        async with connect(f"ws://{host}/ws", origin=f"http://{host}") as ws:  # type: ignore[arg-type]
            await _until(ws, "kit")
        assert server.counters["foreign_origin"] == 1

    _run(None, body)
