"""docs/live-control.md's Python client runs as written against a stand-in node, and every message it sends is one
the rig's own decoder takes (its types, its argument counts): a reader copies it to drive a rig from their code."""

from __future__ import annotations

import re
import socket
import threading
import types
from collections.abc import Iterator
from pathlib import Path

import pytest

from common.clock import answer_ping
from common.messages import ClockPing, Impact, OscMessage, decode, encode
from common.messages.interaction import RouteRemove, RouteSet
from common.messages.score import LiveNote
from common.transport import parse_address
from tests.ports import free_ports
from tests.waiting import until

LIVE_CONTROL_MD = Path(__file__).resolve().parents[2] / "docs" / "live-control.md"
RIG_OFFSET_S = 1000.0
"""The stand-in's rig time minus the client's clock (time.monotonic()), seconds."""


def _example() -> types.ModuleType:
    text = LIVE_CONTROL_MD.read_text(encoding="utf-8")
    section = text.split("## 8. A client in Python", 1)[1]
    code = re.search(r"```python\n(.*?)```", section, re.S)
    assert code, "no Python example under '8. A client in Python'"
    module = types.ModuleType("live_control_example")
    exec(compile(code.group(1), str(LIVE_CONTROL_MD), "exec"), module.__dict__)
    return module


class StandIn:
    """Physics and interaction on one socket: answers clock pings on a rig clock RIG_OFFSET_S ahead of the client's,
    takes a route, answers each live note with two copies of an impact at its rig time (and a refused note's
    refusal), and keeps every message it received. A datagram the rig would drop fails the test."""

    def __init__(self, port: int) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", port))
        self.sock.settimeout(0.05)
        self.received: list[OscMessage] = []
        self.errors: list[str] = []
        self.route: tuple[str, int] | None = None
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        import time

        while not self.stop.is_set():
            try:
                data, source = self.sock.recvfrom(65536)
            except TimeoutError:
                continue
            except OSError:
                return
            decoded = decode(data)
            self.errors += [str(e) for e in decoded.errors]
            for message in decoded.messages:
                self.received.append(message)
                if isinstance(message, ClockPing):
                    now = time.monotonic() + RIG_OFFSET_S
                    self.sock.sendto(encode(answer_ping(message, now, now)), source)
                elif isinstance(message, RouteSet):
                    self.route = parse_address(message.to)
                elif isinstance(message, LiveNote) and self.route is not None:
                    impact = Impact(seq=len(self.received), time=message.time, instrument="snare", zone="centre",
                                    r=0.3, theta=1.6, velocity=3.2, impulse=0.0, peak_force=0.0, duration=0.0,
                                    part="left_stick_tip")
                    for _ in range(2):  # interaction's redundant copies: the client plays the first
                        self.sock.sendto(encode(impact), self.route)

    def close(self) -> None:
        self.stop.set()
        self.thread.join(timeout=5)
        self.sock.close()


@pytest.fixture
def stand_in() -> Iterator[tuple[StandIn, int]]:
    node_port, client_port = free_ports(2)
    node = StandIn(node_port)
    yield node, client_port
    node.close()


def test_the_client_syncs_plays_hears_and_unroutes(stand_in: tuple[StandIn, int],
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    node, client_port = stand_in
    example = _example()
    example.PHYSICS = example.INTERACTION = ("127.0.0.1", node.sock.getsockname()[1])
    example.main(port=client_port, notes=2)
    out = capsys.readouterr().out
    assert until(lambda: any(isinstance(m, RouteRemove) for m in node.received)), "the route was not removed"
    assert not node.errors, node.errors  # each message decodes: right types and counts
    kinds = [type(m) for m in node.received]
    assert kinds.count(LiveNote) == 2
    assert kinds[-1] is RouteRemove and RouteSet in kinds
    route = next(m for m in node.received if isinstance(m, RouteSet))
    assert route.to == f"127.0.0.1:{client_port}" and route.instruments == "*"
    notes = [m for m in node.received if isinstance(m, LiveNote)]
    assert [n.pitch for n in notes] == [36, 38] and all(n.channel == 10 and n.velocity == 100 for n in notes)
    # stamped on the rig clock (the stand-in's, RIG_OFFSET_S ahead), not the client's own
    assert all(n.time > RIG_OFFSET_S for n in notes)
    assert out.count("snare struck at") == 2, out  # one line per impact, not per copy
