"""``batteur echo`` prints a message once, not once per copy: interaction sends each impact (impact end,
damping) several times with one ``seq``, to each of its peers, and a node copies every send to the subscriber
(20 lines per impact on the rig: 5 copies x 4 routes). Other messages with a sequence number (clock pings and
pongs, one per node asking) are not copies of one another. Nodes are fakes on loopback (no discovery)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from common.messages import ClockPong, Impact
from tests.test_tools_qa import FakeNode, batteur


def impact(seq: int) -> Impact:
    return Impact(seq=seq, time=1.0 + seq, instrument="snare", zone="centre", r=0.2, theta=0.0, velocity=2.5,
                  impulse=0.0, peak_force=0.0, duration=0.0, part="left_stick_tip")


@pytest.fixture
def copying_node() -> Iterator[FakeNode]:
    # what a subscriber receives from interaction: the first impact's copies, then the second impact's
    node = FakeNode(stream=[impact(1), impact(1), impact(1), impact(2), impact(2)])
    yield node
    node.close()


def _echo(node: FakeNode, *options: str, pattern: str = "/batteur/impact") -> list[str]:
    proc = batteur("echo", pattern, "--node", f"127.0.0.1:{node.port}", "--count", "2", "--duration", "30", *options)
    try:
        out, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
        proc.wait()
    assert proc.returncode == 0, err
    return out.splitlines()


def test_echo_prints_each_impact_once_whatever_its_copies(copying_node: FakeNode) -> None:
    lines = _echo(copying_node)
    # was "/batteur/impact 1 ..." twice: the second line a copy of the first, the second impact never reached
    assert [line.split()[:2] for line in lines] == [["/batteur/impact", "1"], ["/batteur/impact", "2"]], lines


def test_echo_copies_prints_every_copy(copying_node: FakeNode) -> None:
    lines = _echo(copying_node, "--copies")  # to see the redundancy itself
    assert [line.split()[:2] for line in lines] == [["/batteur/impact", "1"], ["/batteur/impact", "1"]], lines


def test_echo_prints_distinct_messages_that_share_a_seq(pong_node: FakeNode) -> None:
    # the clock master answers two nodes' pings of the same number: two pongs, not one pong and its copy
    lines = _echo(pong_node, pattern="/batteur/clock/pong")
    assert sorted(line.split()[1] for line in lines) == ["'interaction-1'", "'sound-1'"], lines


@pytest.fixture
def pong_node() -> Iterator[FakeNode]:
    node = FakeNode(stream=[ClockPong(node_id=f"{role}-1", seq=7, t_send=1.0, t_receive=2.0, t_reply=2.001)
                            for role in ("sound", "interaction")])
    yield node
    node.close()
