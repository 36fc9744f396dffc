"""``batteur echo`` prints a message once, not once per copy: interaction sends each impact (impact end,
damping) several times with one ``seq``, to each of its peers, and a node copies every send to the subscriber
(20 lines per impact on the rig: 5 copies x 4 routes), and every node that receives it copies it too. Other messages
with a sequence number (clock pings and pongs, one per node asking) are not copies of one another. Nodes are fakes on
loopback (no discovery)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from batteur.tools.echo import FirstCopies
from common.messages import ClockPong, Impact
from tests.ports import free_port
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


def test_echo_prints_an_impact_once_though_every_node_it_crosses_copies_it() -> None:
    # on the rig interaction copies each impact it sends to echo, and sound and graphics each impact they receive:
    # was printed once per node (three identical lines per stroke), as if the drummer had struck three times
    nodes = [FakeNode(port=free_port(), stream=[impact(1), impact(2)], node_id=role)
             for role in ("interaction", "sound")]
    try:
        # --count 3: reached only if a copy is printed twice; else the two impacts, until --duration
        proc = batteur("echo", "/batteur/impact", *(a for n in nodes for a in ("--node", f"127.0.0.1:{n.port}")),
                       "--count", "3", "--duration", "4")
        try:
            out, err = proc.communicate(timeout=60)
        finally:
            proc.kill()
            proc.wait()
    finally:
        for node in nodes:
            node.close()
    assert proc.returncode == 0, err
    assert sorted(line.split()[1] for line in out.splitlines()) == ["1", "2"], out


def test_copies_are_told_by_content_whichever_node_sent_them() -> None:
    printed = FirstCopies()
    assert printed.first(impact(1))
    assert not printed.first(impact(1))  # the same impact, copied by another node (or a redundant copy)
    assert printed.first(impact(2))
    mapped = impact(1).model_copy(update={"velocity": 9.0})  # a route with a mapped field: another message
    assert printed.first(mapped)
    pong = ClockPong(node_id="a", seq=1, t_send=1.0, t_receive=2.0, t_reply=2.0)
    assert printed.first(pong) and printed.first(pong)  # not sent redundantly: every one printed


def test_first_copies_memory_is_bounded() -> None:
    printed = FirstCopies(size=2)
    for seq in (1, 2, 3):
        assert printed.first(impact(seq))
    assert len(printed) == 2
    assert printed.first(impact(1))  # forgotten: long gone on a rig (its copies come within 20 ms)
