"""``batteur echo`` hides its own heartbeat traffic, and only that: a user's identical messages are printed.

Echo asks each node for its Health every second (a Hello from an endpoint of its own); the node copies that Hello and
its answers to echo's subscription (``//*``, ``/batteur/*``). A copy is the node's packet as sent: it says neither
where it went nor where it came from, and a ClockStatus (no timestamp) or physics' Skeleton is the same bytes
whoever it answers. Echo hid every copy with an answer's content for 3 s after each heartbeat, so a user's own
``batteur ls`` ClockStatus (and physics' periodic Skeleton) were never printed; and it printed its own Skeleton copy
when read before the answer. Each answer now stands for one copy of its content from its node.

A stand-in node on loopback answers each Hello as a node does (Health, ClockStatus, Skeleton: each sent, then copied
to the subscriber), then copies to echo a ClockStatus and a Skeleton of the same content sent to another client.
"""

from __future__ import annotations

import select
import socket
import threading
from collections.abc import Iterator

import pytest

from batteur.tools import echo
from common.messages import ClockStatus, Health, Hello, Skeleton, Subscribe, encode, parse_packet
from common.messages.system import TOOL_ROLE
from tests.ports import free_port

pytestmark = pytest.mark.timeout(60)

USER_COPIES = 3
"""Heartbeats after which the stand-in copies to echo what it sent another client (each time the same content)."""

STATUS = ClockStatus(node_id="physics-1", synced=1, offset_s=0.0, uncertainty_s=0.0, round_trip_s=-1.0, samples=0,
                     rejected=0, outliers=0, steps=0, foreign_pongs=0, master="physics-1")
SKELETON = Skeleton(layout=1, names=("pelvis", "torso"))


class StandIn:
    """A node on 127.0.0.1 that copies what it receives and sends to its one subscriber, answers a tool's Hello as
    a physics node does, and after each heartbeat (up to :data:`USER_COPIES`) copies the same ClockStatus and
    Skeleton sent to another client (a user's ``batteur ls``, a renderer's Hello)."""

    def __init__(self) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", free_port()))
        self.address = f"127.0.0.1:{self.sock.getsockname()[1]}"
        self.subscriber: tuple[str, int] | None = None
        self.heartbeats = 0
        """Hellos answered while subscribed to (echo's heartbeats)."""
        self.user_copies = 0
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self.serve, daemon=True)

    def copy(self, data: bytes) -> None:
        if self.subscriber is not None:
            self.sock.sendto(data, self.subscriber)

    def serve(self) -> None:
        answered = 0
        while not self.stop.is_set():
            ready, _, _ = select.select([self.sock], [], [], 0.05)
            if not ready:
                continue
            data, source = self.sock.recvfrom(65536)
            for raw in parse_packet(data):
                if raw.address == Subscribe.ADDRESS:
                    self.subscriber = source
                elif raw.address == Hello.ADDRESS:
                    self.copy(data)  # copied as received
                    answered += 1
                    health = Health(node_id="physics-1", role="physics", protocol=1, time=100.0 + answered,
                                    rate_hz=1000.0, target_rate_hz=1000.0, overruns=0, messages_in=0, messages_out=0,
                                    dropped=0, dropped_malformed=0, dropped_unknown=0, dropped_type=0,
                                    dropped_range=0, dropped_other=0, late=0, peers=0)
                    for answer in (health, STATUS, SKELETON):  # as a node sends: the answer, then its copy
                        self.sock.sendto(encode(answer), source)
                        self.copy(encode(answer))
                    if self.subscriber is not None:
                        self.heartbeats += 1
                        if self.user_copies < USER_COPIES:  # the same content, sent to another: the rig's traffic
                            self.copy(encode(STATUS))
                            self.copy(encode(SKELETON))
                            self.user_copies += 1

    def close(self) -> None:
        self.stop.set()
        self.thread.join(5)
        self.sock.close()


@pytest.fixture
def node() -> Iterator[StandIn]:
    node = StandIn()
    node.thread.start()
    yield node
    node.close()


def test_echo_prints_the_users_answers_and_not_its_own(node: StandIn, capsys: pytest.CaptureFixture[str]) -> None:
    code = echo.main(["//*", "--node", node.address, "--count", str(2 * USER_COPIES), "--duration", "20"])
    out = capsys.readouterr().out.splitlines()
    assert code == 0
    status = echo.format_message(STATUS, False)
    skeleton = echo.format_message(SKELETON, False)
    # exactly the other client's copies, in the order sent: none of echo's Hellos, Healths, statuses or skeletons
    assert out == [status, skeleton] * USER_COPIES, out
    assert node.user_copies == USER_COPIES


def test_each_answer_hides_one_copy() -> None:
    """The unit rule: an answer to echo's Hello hides one copy of its content from its node (no time window)."""
    target = echo.Target("127.0.0.1", 9000, "physics", "physics-1", ip="127.0.0.1")
    hello = Hello(role=TOOL_ROLE, node_id="batteur-echo-1", protocol=1, osc_port=5555)
    presence = echo.Presence([target], [target], 0.0, hello)
    source = target.socket_address
    presence.answer(STATUS, source, 0.5)
    assert presence.ours(hello, source, 0.5)
    assert presence.ours(STATUS, "127.0.0.1:9001", 0.5) is False  # another node's: not our answer
    assert presence.ours(STATUS, source, 0.5)  # our answer's copy
    assert presence.ours(STATUS, source, 0.6) is False  # the same sent to a user's batteur ls: printed
    presence.answer(SKELETON, source, 1.5)
    assert presence.ours(SKELETON, source, 1.5 + 2 * echo.HEARTBEAT_S) is False  # its copy never came: forgotten
