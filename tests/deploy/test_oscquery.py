"""OSCQuery: the namespace generated from the models, served over HTTP, values streamed over WebSocket."""

from __future__ import annotations

import asyncio
import ipaddress
import json
import urllib.error
import urllib.request
from typing import Any

import pytest
from websockets.asyncio.client import connect

from common.config import load_settings
from common.messages import REGISTRY, decode, encode
from common.messages.sound import SoundLevel, SoundResonances
from common.oscquery import ACCESS_READ, ACCESS_READ_WRITE, OscQueryServer, build_tree, find, namespace_models
from common.runtime import Node
from common.transport import UdpEndpoint
from tests.recording_core import RecordingCore
from tests.waiting import wait_for

pytestmark = pytest.mark.timeout(60)


def http_get(url: str) -> tuple[int, Any]:
    try:
        with urllib.request.urlopen(url, timeout=5) as response:
            body = response.read()
            return response.status, json.loads(body) if body else None
    except urllib.error.HTTPError as exc:
        return exc.code, None


async def get(url: str) -> tuple[int, Any]:
    return await asyncio.get_running_loop().run_in_executor(None, http_get, url)


def test_every_model_appears_in_the_namespace_of_some_role_with_its_attributes() -> None:
    covered: set[str] = set()
    for role in ("physics", "interaction", "sound", "graphics"):
        models = namespace_models(role)
        covered |= set(models)
        tree = build_tree(models)
        for address, (model, _access) in models.items():
            node = find(tree, address)
            assert node is not None and node["FULL_PATH"] == address
            assert node["ACCESS"] in (ACCESS_READ, ACCESS_READ_WRITE)
            assert node["DESCRIPTION"]
            fixed = [f for f in model.wire_fields() if not f.variadic]
            assert len(node["TYPE"]) == sum(2 if f.kind.value == "t" else 1 for f in fixed)
            if node["TYPE"]:
                assert len(node["RANGE"]) == len(node["TYPE"])
    recogniser_only = {m.ADDRESS for m in REGISTRY if m.ADDRESS.startswith("/batteur/recogniser/")}
    assert covered | recogniser_only == {m.ADDRESS for m in REGISTRY}
    # an unknown role serves everything
    assert set(namespace_models("custom")) == {m.ADDRESS for m in REGISTRY}


def test_sound_namespace_details() -> None:
    tree = build_tree(namespace_models("sound"))
    level = find(tree, "/batteur/sound/level")
    assert level is not None
    assert level["TYPE"] == "sf" and level["ACCESS"] == ACCESS_READ_WRITE
    assert level["RANGE"] == [None, {"MIN": -80, "MAX": 12}]
    model = find(tree, "/batteur/sound/model")
    assert model is not None and model["RANGE"][1] == {"VALS": ["modal", "sample", "synth"]}
    impact = find(tree, "/batteur/impact")
    assert impact is not None and impact["ACCESS"] == ACCESS_READ and impact["TYPE"].startswith("iif")
    assert "CONTENTS" in impact and "end" in impact["CONTENTS"]  # /batteur/impact/end below it
    assert find(tree, "/batteur/physics/grip") is None  # not the sound node's
    assert find(tree, "/batteur") is not None and find(tree, "/nope") is None


def test_node_serves_oscquery_values_and_streams_changes() -> None:
    async def main() -> None:
        core = RecordingCore()
        node = Node(core, load_settings({"role": "sound", "discovery": False, "clock_master": "self"}))
        task = asyncio.ensure_future(node.run())
        await wait_for(lambda: node.oscquery is not None)
        server = node.oscquery
        assert isinstance(server, OscQueryServer) and node.endpoint is not None
        base = f"http://127.0.0.1:{server.port}"
        status, root = await get(base + "/")
        assert status == 200 and root["FULL_PATH"] == "/"
        assert "sound" in root["CONTENTS"]["batteur"]["CONTENTS"]
        status, info = await get(base + "/?HOST_INFO")
        assert status == 200 and info["OSC_PORT"] == node.endpoint.port and info["OSC_TRANSPORT"] == "UDP"
        assert info["EXTENSIONS"]["LISTEN"] is True and info["WS_PORT"] == server.port
        status, level = await get(base + "/batteur/sound/level")
        assert status == 200 and "VALUE" not in level
        assert (await get(base + "/batteur/nothing"))[0] == 404
        assert (await get(base + "/batteur/sound/level?TYPE"))[1] == {"TYPE": "sf"}
        assert (await get(base + "/batteur/sound/level?CLIPMODE"))[0] == 204

        sender = await UdpEndpoint.open()
        sender.send(SoundLevel(instrument="snare", gain_db=-6.0), node.endpoint.local_address)
        await wait_for(lambda: len(core.handled) == 1)
        status, value = await get(base + "/batteur/sound/level?VALUE")
        assert status == 200 and value == {"VALUE": ["snare", -6.0]}

        async with connect(f"ws://127.0.0.1:{server.port}/") as ws:
            await ws.send(json.dumps({"COMMAND": "LISTEN", "DATA": "/batteur/sound/level"}))
            await wait_for(lambda: bool(server.listeners.get("/batteur/sound/level")))
            sender.send(SoundLevel(instrument="kick", gain_db=3.0), node.endpoint.local_address)
            frame = await asyncio.wait_for(ws.recv(), 5.0)
            assert isinstance(frame, bytes)
            assert decode(frame).messages == [SoundLevel(instrument="kick", gain_db=3.0)]
            # OSC over the WebSocket reaches the node through the same checks
            await ws.send(encode(SoundResonances(instrument="snare", gains=(1.0, 0.5))))
            await ws.send(b"not osc at all")
            await wait_for(lambda: len(core.handled) == 3)
            assert core.handled[-1] == SoundResonances(instrument="snare", gains=(1.0, 0.5))
            assert node.endpoint.stats.dropped_total == 1
            await ws.send(json.dumps({"COMMAND": "IGNORE", "DATA": "/batteur/sound/level"}))
            await wait_for(lambda: not server.listeners.get("/batteur/sound/level"))
        sender.close()
        node.request_stop()
        await asyncio.wait_for(task, 3.0)

    asyncio.run(main())


def test_clients_outside_the_allow_list_are_refused() -> None:
    async def main() -> None:
        server = OscQueryServer("n", "sound", "127.0.0.1", 9, allow=[ipaddress.ip_network("10.0.0.0/8")])
        await server.start("127.0.0.1", 0)
        status, _ = await get(f"http://127.0.0.1:{server.port}/")
        assert status == 403 and server.refused == 1
        await server.stop()

    asyncio.run(main())


def test_oscquery_can_be_turned_off() -> None:
    async def main() -> None:
        node = Node(RecordingCore(), load_settings({"role": "sound", "discovery": False, "clock_master": "self",
                                                    "oscquery": False}))
        task = asyncio.ensure_future(node.run())
        await wait_for(lambda: node.endpoint is not None)
        await asyncio.sleep(0.05)
        assert node.oscquery is None
        node.request_stop()
        await asyncio.wait_for(task, 3.0)

    asyncio.run(main())
