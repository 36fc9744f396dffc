"""The graphics view's node table lists the rig's nodes, not the command-line tools that say Hello to them:
``batteur rig``'s readiness probe (a Hello to each service until it answers with its Health) was listed as a node
(role ``cli``, id ``batteur-rig``), as was ``batteur ls``'s. The probe still gets its answer."""

from __future__ import annotations

import asyncio
import io
import time

from batteur import rig
from common.config import load_settings
from common.messages import PROTOCOL_VERSION, Health, Hello
from common.runtime import Node
from common.transport import UdpEndpoint
from services.graphics.core import GraphicsCore, GraphicsSettings
from tests.waiting import wait_for


def _health(role: str, node_id: str) -> Health:
    return Health(node_id=node_id, role=role, protocol=PROTOCOL_VERSION, time=1.0, rate_hz=100.0,
                  target_rate_hz=100.0, overruns=0, messages_in=0, messages_out=0, dropped=0, dropped_malformed=0,
                  dropped_unknown=0, dropped_type=0, dropped_range=0, dropped_other=0, late=0, peers=1)


def test_the_rigs_readiness_probe_is_not_listed_as_a_node() -> None:
    """A graphics node on loopback, asked by the rig's own readiness wait whether it is up, then greeted by a sound
    node: the table lists the sound node only."""
    async def main() -> tuple[list[dict[str, object]], str]:
        core = GraphicsCore(GraphicsSettings(latency=0.0, clock="rig"))
        node = Node(core, load_settings({"role": "graphics", "discovery": False, "oscquery": False,
                                         "clock_master": "self"}))
        task = asyncio.ensure_future(node.run())
        sound = await UdpEndpoint.open()
        try:
            await wait_for(lambda: node.endpoint is not None and node.core_started, timeout=30)
            assert node.endpoint is not None
            out = io.StringIO()
            the_rig = rig.Rig([rig.ServicePlan("graphics", node.endpoint.port)], stop_timeout_s=5.0, out=out,
                              err=io.StringIO())
            ready = rig.ReadyWait(timeout_s=30.0, host="127.0.0.1", epoch=time.time(), play_at_s=1.0)
            await the_rig._wait_ready(ready, time.monotonic())  # returns once the node answered the probe
            sound.send(Hello(role="sound", node_id="sound-1", protocol=PROTOCOL_VERSION, osc_port=sound.port),
                       node.endpoint.local_address)
            await wait_for(lambda: "sound-1" in core.nodes, timeout=30)
            return core.status(node.clock.now())["nodes"], out.getvalue()
        finally:
            sound.close()
            node.request_stop()
            await asyncio.wait_for(task, 30)

    nodes, said = asyncio.run(main())
    assert "services up" in said, said  # the probe was answered, as before
    assert [(n["role"], n["id"]) for n in nodes] == [("sound", "sound-1")]  # was also ("cli", "batteur-rig")


def test_tools_are_not_listed_and_nodes_are() -> None:
    core = GraphicsCore(GraphicsSettings(latency=0.0, clock="rig"))
    for hello in (Hello(role="cli", node_id="batteur-ls", protocol=PROTOCOL_VERSION, osc_port=40000),
                  Hello(role="physics", node_id="physics-1", protocol=PROTOCOL_VERSION, osc_port=9101)):
        core.handle(hello, 1.0, "127.0.0.1:40000")
    core.handle(_health("interaction", "interaction-1"), 1.0, "127.0.0.1:9102")
    assert [(n["role"], n["id"]) for n in core.status(1.5)["nodes"]] == [("interaction", "interaction-1"),
                                                                          ("physics", "physics-1")]
