"""A node off loopback gives its allow-list (``--allow``, plus loopback, as its transport takes it) to discovery, so a
peer announced outside it is not added to the peer table (docs/security.md). Until 7 Dec discovery got no
allow-list: such a peer was added, the node sent it Hellos and Health, and dropped its answers as ``not_allowed``.

The node runs in-process with a discovery factory that records its keywords (no mDNS); its socket is bound to
loopback although its settings say 0.0.0.0 (nothing listens on the machine's interfaces). The real
:class:`~common.discovery.Discovery` is built from those keywords (not started) and judges two announced peers.
"""

from __future__ import annotations

import asyncio
from typing import Any

import pytest

from common.config import load_settings
from common.discovery import Discovery, Rejection, peer_from_service
from common.peers import Peer
from common.runtime import Node
from common.transport import UdpEndpoint
from tests.null_core import NullCore

pytestmark = pytest.mark.timeout(60)


class _Recorder:
    """Discovery that records the keywords it was built with, finds nothing and announces nothing."""

    kwargs: dict[str, Any] = {}

    def __init__(self, **kwargs: Any) -> None:
        _Recorder.kwargs = kwargs

    async def start(self) -> None:
        pass

    async def stop(self) -> None:
        pass


def _discovery_keywords(monkeypatch: pytest.MonkeyPatch, settings: dict[str, Any]) -> dict[str, Any]:
    real_open = UdpEndpoint.open

    async def open_on_loopback(host: str = "127.0.0.1", *args: Any, **kwargs: Any) -> UdpEndpoint:
        return await real_open("127.0.0.1", *args, **kwargs)

    monkeypatch.setattr(UdpEndpoint, "open", open_on_loopback)

    async def main() -> None:
        node = Node(NullCore(), load_settings({"role": "sound", "clock_master": "self", "oscquery": False,
                                               "interfaces": ["127.0.0.1"], **settings}),
                    discovery_factory=_Recorder)
        await node.start()
        await node.stop()

    _Recorder.kwargs = {}
    asyncio.run(main())
    return _Recorder.kwargs


def _judge(discovery: Discovery, address: str) -> Peer | Rejection:
    """What discovery makes of a peer announcing ``address`` (as its browser would, on a LAN interface)."""
    properties = {"role": "physics", "proto": "1", "node_id": "physics-x", "port": "9101"}
    return peer_from_service("physics-x._osc._udp.local.", 9101, properties, [address], allow_loopback=False,
                             allowed=discovery.effective_allowed)


def test_discovery_ignores_a_peer_outside_the_allow_list(monkeypatch: pytest.MonkeyPatch) -> None:
    kwargs = _discovery_keywords(monkeypatch, {"host": "0.0.0.0", "allow": ["192.168.1.0/24"]})
    assert kwargs.get("allowed") == ["192.168.1.0/24", "127.0.0.0/8", "::1/128"]  # the transport's list
    discovery = Discovery(**kwargs)
    inside, outside = _judge(discovery, "192.168.1.20"), _judge(discovery, "10.1.2.3")
    assert isinstance(inside, Peer) and inside.host == "192.168.1.20"
    assert isinstance(outside, Rejection) and outside.reason == "not_allowed"


def test_a_node_on_loopback_gives_discovery_no_allow_list(monkeypatch: pytest.MonkeyPatch) -> None:
    """On loopback the transport takes any source (only this machine can reach it): discovery keeps its own rule
    (loopback peers only, for a node on loopback interfaces)."""
    assert _discovery_keywords(monkeypatch, {"host": "127.0.0.1"}).get("allowed", "absent") is None
