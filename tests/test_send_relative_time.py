"""``batteur send`` with a rig time written ``+SECONDS``: that long after the destination node's rig time, which
send asks the node for first (the Health it answers a Hello, as ``batteur ls``). A user could not learn the rig
time in time: Health's time + 1 s was already past when ``send`` ran."""

from __future__ import annotations

import select
import socket
import threading
from collections.abc import Iterator

import pytest

from batteur.tools import send
from common.messages import Health, RawMessage, encode, parse_packet
from tests.ports import free_port

pytestmark = pytest.mark.timeout(60)

RIG_TIME_S = 1000.25
"""The stand-in node's rig time (exact in the wire's whole seconds and float32 fraction)."""


class StandIn:
    """A node on 127.0.0.1 that answers a Hello with a Health at :data:`RIG_TIME_S` (unless ``silent``) and keeps
    every other message it receives."""

    def __init__(self, silent: bool = False) -> None:
        self.silent = silent
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", free_port()))
        self.address = f"127.0.0.1:{self.sock.getsockname()[1]}"
        self.hellos = 0
        self.received: list[RawMessage] = []
        self.got = threading.Event()
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self.serve, daemon=True)

    def serve(self) -> None:
        health = Health(node_id="physics-1", role="physics", protocol=1, time=RIG_TIME_S, rate_hz=1000.0,
                        target_rate_hz=1000.0, overruns=0, messages_in=0, messages_out=0, dropped=0,
                        dropped_malformed=0, dropped_unknown=0, dropped_type=0, dropped_range=0, dropped_other=0,
                        late=0, peers=0)
        while not self.stop.is_set():
            ready, _, _ = select.select([self.sock], [], [], 0.05)
            if not ready:
                continue
            data, source = self.sock.recvfrom(65536)
            for raw in parse_packet(data):
                if raw.address == "/batteur/hello":
                    self.hellos += 1
                    if not self.silent:
                        self.sock.sendto(encode(health), source)
                else:
                    self.received.append(raw)
                    self.got.set()

    def close(self) -> None:
        self.stop.set()
        self.thread.join(5)
        self.sock.close()


def stand_in(silent: bool) -> Iterator[StandIn]:
    node = StandIn(silent)
    node.thread.start()
    yield node
    node.close()


@pytest.fixture
def node() -> Iterator[StandIn]:
    yield from stand_in(silent=False)


@pytest.fixture
def silent_node() -> Iterator[StandIn]:
    yield from stand_in(silent=True)


@pytest.mark.parametrize(("time", "expected"), [("+2", RIG_TIME_S + 2), ("+0.5", RIG_TIME_S + 0.5)])
def test_a_relative_time_is_after_the_nodes_rig_time(node: StandIn, time: str, expected: float) -> None:
    assert send.main(["/batteur/score/transport", "play", time, "3", "--to", node.address]) == 0
    assert node.got.wait(5)
    [play] = node.received
    assert play.address == "/batteur/score/transport"
    whole, fraction = play.args[1], play.args[2]
    assert isinstance(whole, int) and isinstance(fraction, float)
    assert (play.args[0], whole + fraction, play.args[3]) == ("play", expected, 3.0)
    assert node.hellos == 1


def test_an_absolute_time_asks_the_node_nothing(node: StandIn) -> None:
    assert send.main(["/batteur/score/transport", "play", "12.25", "0", "--to", node.address]) == 0
    assert node.got.wait(5)
    assert [r.args for r in node.received] == [["play", 12, 0.25, 0.0]] and node.hellos == 0


def test_a_node_that_does_not_say_its_rig_time_is_one_line_and_exit_1(silent_node: StandIn,
                                                                      capsys: pytest.CaptureFixture[str]) -> None:
    code = send.main(["/batteur/score/transport", "play", "+2", "0", "--to", silent_node.address, "--timeout",
                      "0.3"])
    err = capsys.readouterr().err
    assert code == 1
    assert err.splitlines() == [f"batteur send: error: no rig time from {silent_node.address} within 0.3 s (its Health "
                                "did not come: is a Batteur node running there?); +SECONDS needs it, not sent"]
    assert silent_node.hellos == 1 and silent_node.received == []  # asked, and nothing sent


@pytest.mark.parametrize("time", ["+", "+x", "+-1", "++1", "+inf", "+nan"])
def test_a_bad_relative_time_is_refused_before_any_node_is_asked(silent_node: StandIn, time: str,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    code = send.main(["/batteur/score/transport", "play", time, "0", "--to", silent_node.address])
    err = capsys.readouterr().err
    assert code == 2
    assert f"TIME: +SECONDS must be a finite number of seconds, 0 or more, got {time!r}" in err
    assert silent_node.hellos == 0


def test_the_help_says_how_to_write_a_relative_time(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        send.main(["--help"])
    assert "+SECONDS is that long after the node's rig time" in " ".join(capsys.readouterr().out.split())
