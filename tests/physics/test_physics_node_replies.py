"""The physics node over loopback (no discovery): a refused control comes back to its sender as
/batteur/physics/rejected naming the address and the reason (``batteur send --replies`` then fails); an accepted
one gets no answer."""

from __future__ import annotations

import socket
import subprocess
import sys
import time
from collections.abc import Iterator

import pytest

from batteur.tools import send
from common.messages import Health, Hello, decode, encode
from common.messages.physics import CartesianTarget, PhysicsRejected
from tests.ports import free_port

pytestmark = pytest.mark.timeout(180)

BAD = ["left_hand", "1000", "0.0", "0", "4", "1", "0", "0", "0"]  # 4 m in front of the drummer: out of reach
GOOD = ["right_hand", "1000", "0.0", "0.1", "0.45", "0.75", "0", "0", "0"]  # over the snare


def _answer(sock: socket.socket) -> object:
    """The first message of the next datagram ``sock`` receives."""
    return decode(sock.recv(65536)).messages[0]


def _target(args: list[str]) -> CartesianTarget:
    limb, whole, fraction, *rest = args
    return CartesianTarget.from_args([limb, int(whole), float(fraction), *map(float, rest)])


@pytest.fixture(scope="module")
def physics_node() -> Iterator[str]:
    """A drummer physics node on 127.0.0.1 (no discovery, no OSCQuery), once it answers a Hello: its address."""
    port = free_port()
    proc = subprocess.Popen([sys.executable, "-m", "batteur", "physics", "--host", "127.0.0.1", "--port", str(port),
                             "--no-discovery", "--no-oscquery", "--pose-rate-hz", "0"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    hello = encode(Hello(role="test", node_id="test", protocol=1, osc_port=0))
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            sock.bind(("127.0.0.1", 0))
            sock.settimeout(0.5)
            deadline = time.monotonic() + 150.0
            while True:  # the node listens once its scene is built and its planner started
                assert proc.poll() is None, "the physics node exited"
                assert time.monotonic() < deadline, "the physics node never answered"
                sock.sendto(hello, ("127.0.0.1", port))
                try:
                    if isinstance(_answer(sock), Health):
                        break
                except (TimeoutError, ConnectionRefusedError):
                    continue
        yield f"127.0.0.1:{port}"
    finally:
        proc.terminate()
        proc.wait(timeout=30)


def test_a_refused_target_is_answered_and_batteur_send_fails(physics_node: str,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    assert send.main(["/batteur/physics/target", *BAD, "--to", physics_node, "--replies", "2"]) == 1
    out = capsys.readouterr().out
    assert f"{physics_node} /batteur/physics/rejected /batteur/physics/target" in out and "unreachable" in out
    assert send.main(["/batteur/physics/target", *GOOD, "--to", physics_node, "--replies", "0.5"]) == 0
    assert "rejected" not in capsys.readouterr().out


def test_only_the_refused_one_of_two_targets_is_answered(physics_node: str) -> None:
    """A good target then a bad one from the same socket: the node handles them in order, so the first answer
    being the bad one's means the good one got none."""
    host, port = physics_node.rsplit(":", 1)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        sock.settimeout(30.0)
        sock.sendto(encode(_target(GOOD)), (host, int(port)))
        sock.sendto(encode(_target(BAD)), (host, int(port)))
        reply = _answer(sock)
        assert isinstance(reply, PhysicsRejected) and reply.address == "/batteur/physics/target"
        assert "[0.0, 4.0, 1.0] is unreachable" in reply.reason


def test_an_undecodable_target_is_answered_by_the_nodes_transport(physics_node: str) -> None:
    from common.messages import encode_raw

    host, port = physics_node.rsplit(":", 1)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        sock.settimeout(30.0)
        sock.sendto(encode_raw("/batteur/physics/target", ["left_hand", 1000]), (host, int(port)))
        reply = _answer(sock)
        assert isinstance(reply, PhysicsRejected) and reply.address == "/batteur/physics/target"
        assert "wrong_arity" in reply.reason
