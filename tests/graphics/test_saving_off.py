"""Saving off (a node started without ``--kit-dir``, as ``batteur rig`` does): the page is told at connect, and a
save pressed anyway is refused with a hint a rig user can follow, not logged and counted as a malformed message.

Was: "bad page message" WARNING and ``page_errors`` for every press of *save kit* or *save pose*, a hint naming only
the node's own option, and nothing told the page before the press."""

from __future__ import annotations

import asyncio
import json
import logging
from pathlib import Path
from typing import Any

import pytest
from websockets.asyncio.client import connect

from services.graphics.core import GraphicsCore, GraphicsSettings
from services.graphics.server import ViewServer


def _server(kit_dir: Path | None) -> ViewServer:
    return ViewServer(GraphicsCore(GraphicsSettings(latency=0.0, clock="rig")), kit_dir=kit_dir)


def test_a_save_without_a_kit_directory_is_refused_not_a_page_error(caplog: pytest.LogCaptureFixture) -> None:
    server = _server(None)
    caplog.set_level(logging.INFO, logger="batteur.graphics")
    kit = server.core.kit.model_dump(mode="json")
    saves = ({"type": "save_kit", "file": "a.yaml", "kit": kit}, {"type": "save_pose", "name": "SNARE.left_hand.UP"})
    for msg in saves:
        reply = server.handle_page_message(json.dumps(msg))
        assert reply is not None and reply["type"] == "saved" and reply["ok"] is False
        assert "--kit-dir DIR" in reply["error"] and "batteur rig: its --kit-dir DIR" in reply["error"], reply
    assert server.counters["page_errors"] == 0
    assert server.counters["saves_refused"] == 2
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING], caplog.text
    # a malformed message is still one
    assert server.handle_page_message(json.dumps({"type": "bogus"}))["ok"] is False  # type: ignore[index]
    assert server.counters["page_errors"] == 1


@pytest.mark.parametrize("with_dir", [False, True])
def test_the_page_is_told_at_connect_whether_saving_works(tmp_path: Path, with_dir: bool) -> None:
    async def main() -> dict[str, Any]:
        server = _server(tmp_path if with_dir else None)
        port = await server.start("127.0.0.1", 0)
        try:
            async with connect(f"ws://127.0.0.1:{port}/ws") as ws:
                while True:
                    message = json.loads(await asyncio.wait_for(ws.recv(), 5))
                    if message["type"] == "saving":
                        return message  # type: ignore[no-any-return]
        finally:
            await server.close()

    saving = asyncio.run(main())
    assert saving["enabled"] is with_dir
    if with_dir:
        assert saving["reason"] is None
    else:
        assert "batteur rig: its --kit-dir DIR" in saving["reason"]
