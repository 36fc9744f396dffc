"""``batteur graphics --editor {local,all,off}``: who may use the page's kit and pose editor. A teacher's rig served
the view on 0.0.0.0:8080 to the whole classroom, and every student's browser had the pose editor, which drives the
drummer's posture and saves files. By default (local) pages opened on the graphics node's machine get the editor;
pages from other machines get the view only: told at connect (the page hides its editor button), their editor
messages refused and counted.

Over the WebSocket, as a page talks: in-process on loopback, and in network namespaces for a page on another
machine (never on the host's interfaces)."""

from __future__ import annotations

import asyncio
import json
import re
import sys
import time
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any

import pytest
from websockets.asyncio.client import connect

from common.kit import load_kit
from services.graphics.server import ViewServer
from tests.graphics.test_server import _run as run_view
from tests.netns import Namespace, NetnsLab, NsProcess

from .conftest import GraphicsNodeProcess, needs_browser, open_page

pytestmark = pytest.mark.timeout(120)


def _run(editor: str, kit_dir: Path | None, body: Callable[[ViewServer, str], Awaitable[None]]) -> None:
    run_view(kit_dir, body, editor=editor)


async def _until(ws: Any, kind: str) -> dict[str, Any]:
    while True:
        message = json.loads(await asyncio.wait_for(ws.recv(), 5))
        if message["type"] == kind:
            return message  # type: ignore[no-any-return]


def test_a_page_on_the_nodes_machine_gets_the_editor_by_default(tmp_path: Path) -> None:
    async def body(server: ViewServer, host: str) -> None:
        async with connect(f"ws://{host}/ws") as ws:
            assert await _until(ws, "editor") == {"type": "editor", "enabled": True, "reason": None}
            await ws.send(json.dumps({"type": "poser_on"}))
            assert (await _until(ws, "poser"))["body"] in ("live", "rest")  # the editor's body
            await ws.send(json.dumps({"type": "save_kit", "file": "mine.yaml",
                                      "kit": load_kit().model_dump(mode="json")}))
            assert (await _until(ws, "saved"))["ok"] is True
        assert (tmp_path / "mine.yaml").is_file()

    _run("local", tmp_path, body)


@pytest.mark.parametrize("header", [{"X-Forwarded-For": "192.168.1.57"}, {"Forwarded": "for=192.168.1.57"},
                                    {"X-Real-IP": "192.168.1.57"}])
def test_a_page_through_a_local_reverse_proxy_gets_the_view_only(tmp_path: Path, header: dict[str, str]) -> None:
    """A proxy on the node's machine (nginx in front of the view) connects from loopback for a student's browser."""
    async def body(server: ViewServer, host: str) -> None:
        async with connect(f"ws://{host}/ws", additional_headers=header) as ws:
            told = await _until(ws, "editor")
            assert told["enabled"] is False and "view only" in told["reason"]
            await ws.send(json.dumps({"type": "save_kit", "file": "mine.yaml",
                                      "kit": load_kit().model_dump(mode="json")}))
            assert (await _until(ws, "saved"))["ok"] is False
        assert server.counters["edits_refused"] == 1
        assert not (tmp_path / "mine.yaml").exists()

    _run("local", tmp_path, body)


def test_editor_off_refuses_every_page_and_writes_nothing(tmp_path: Path) -> None:
    async def body(server: ViewServer, host: str) -> None:
        async with connect(f"ws://{host}/ws") as ws:
            told = await _until(ws, "editor")
            assert told == {"type": "editor", "enabled": False,
                            "reason": "the editor is off on this node (graphics --editor off)"}
            await ws.send(json.dumps({"type": "poser_on"}))
            refused = await _until(ws, "saved")
            assert refused == {"type": "saved", "ok": False, "error": told["reason"]}
            await ws.send(json.dumps({"type": "poser", "angles": {"head": [10, 0, 0]}, "drive": True}))
            await ws.send(json.dumps({"type": "save_kit", "file": "mine.yaml",
                                      "kit": load_kit().model_dump(mode="json")}))
            assert (await _until(ws, "saved"))["ok"] is False
        assert server.poser is None and server.core._posture is None  # nothing for physics
        assert server.counters["edits_refused"] == 3
        assert list(tmp_path.iterdir()) == []

    _run("off", tmp_path, body)


def test_the_setting_is_a_flag_with_its_choices(capsys: pytest.CaptureFixture[str]) -> None:
    from services.graphics import node

    with pytest.raises(SystemExit):
        node.main(["--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "--editor EDITOR which pages may use the kit and pose editor" in text
    assert "local: pages opened on this machine, other machines get the view only" in text
    assert node.main(["--editor", "students"]) == 2
    assert "editor" in capsys.readouterr().err


# ---------------------------------------------------------------------------- a page on another machine

PAGE = """\
import asyncio, json, sys
from websockets.asyncio.client import connect

async def main():
    async with connect(sys.argv[1]) as ws:
        async def until(kind):
            while True:
                m = json.loads(await asyncio.wait_for(ws.recv(), 10))
                if m["type"] == kind:
                    return m
        print(json.dumps(await until("editor")), flush=True)
        await ws.send(json.dumps({"type": "poser_on"}))
        print(json.dumps(await until("poser" if json.loads(sys.argv[2]) else "saved")), flush=True)

asyncio.run(main())
"""
"""A page: prints the node's ``editor`` message, then the answer to opening the editor (argv[2]: whether it may)."""


def _graphics(ns: Namespace, *flags: str) -> tuple[NsProcess, int]:
    """``batteur graphics`` listening on every address of ``ns``; the process and its HTTP port."""
    proc = ns.popen("taskset", "-c", "0", sys.executable, "-m", "batteur", "graphics", "--host", "0.0.0.0",
                    "--allow", "10.0.0.0/8", "--port", "0", "--http-port", "0", "--no-discovery", "--no-oscquery",
                    "--clock-master", "self", *flags)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        found = re.search(r"graphics view: http://0\.0\.0\.0:(\d+)/", "\n".join(proc.errors))
        if found:
            return proc, int(found.group(1))
        assert proc.popen.poll() is None, proc.describe("graphics exited")
        time.sleep(0.1)
    raise AssertionError(proc.describe("no view line"))


def _page(ns: Namespace, url: str, may_edit: bool) -> list[dict[str, Any]]:
    """What a page in ``ns`` opening ``url`` is told: the editor message, then the answer to opening the editor."""
    proc = ns.python("-c", PAGE, url, json.dumps(may_edit))
    told = proc.expect(lambda m: m.get("type") == "editor", timeout=60)
    answer = proc.expect(lambda m: m.get("type") in ("poser", "saved"), timeout=60)
    assert proc.wait(60) == 0, proc.describe("the page failed")
    return [told, answer]


def test_a_page_from_another_machine_gets_the_view_without_the_editor(netns_lab: NetnsLab) -> None:
    rig_laptop, student = netns_lab.namespace("rigl"), netns_lab.namespace("stud")
    lan, _ = netns_lab.veth(rig_laptop, student)
    proc, port = _graphics(rig_laptop)
    assert "other machines get the view only; the editor is for pages opened on this machine (--editor local)" \
        in "\n".join(proc.errors)
    told, answer = _page(student, f"ws://{lan}:{port}/ws", may_edit=False)
    assert told["enabled"] is False and "this page shows the view only" in told["reason"]
    assert answer == {"type": "saved", "ok": False, "error": told["reason"]}
    # the teacher's browser on the rig laptop, by its LAN address or by loopback: the editor
    for url in (f"ws://{lan}:{port}/ws", f"ws://127.0.0.1:{port}/ws"):
        told, answer = _page(rig_laptop, url, may_edit=True)
        assert told == {"type": "editor", "enabled": True, "reason": None} and answer["type"] == "poser", url


def test_editor_all_opens_it_to_other_machines_and_warns(netns_lab: NetnsLab) -> None:
    rig_laptop, student = netns_lab.namespace("rigl"), netns_lab.namespace("stud")
    lan, _ = netns_lab.veth(rig_laptop, student)
    proc, port = _graphics(rig_laptop, "--editor", "all")
    told, answer = _page(student, f"ws://{lan}:{port}/ws", may_edit=True)
    assert told["enabled"] is True and answer["type"] == "poser"
    assert f"the view's editor is open to every machine that reaches port {port} (--editor all)" \
        in "\n".join(proc.errors)


# ---------------------------------------------------------------------------- the page, in chromium

@needs_browser
def test_a_view_only_page_shows_no_editor_button(tmp_path: Path) -> None:
    """The page hides its editor button (and says why on it) when the node tells it it may not edit."""
    node = GraphicsNodeProcess(tmp_path, extra=["--clock-master", "self", "--editor", "off"])
    node.start()
    try:
        with open_page(node.url, -1) as (page, errors):
            page.wait_for_function("window.batteur.connected && window.batteur.editorAllowed === false",
                                   timeout=10000)
            button = page.locator("#edit-toggle")
            assert button.is_hidden()
            assert button.get_attribute("title") == "the editor is off on this node (graphics --editor off)"
            page.locator("#kit-flag").evaluate("b => b.click()")  # the kit flag, shown on a kit change, opens nothing
            assert page.evaluate("window.batteur.editing") is False
            assert page.locator("#editor").is_hidden()
            assert errors == []
    finally:
        node.close()
