"""``batteur send --to ROLE`` refuses a control that nodes of that role ignore (a live note sent to interaction: a
score is physics's), naming the role that takes it, before browsing. Such a message was sent, taken by the node
without a drop or an answer (its namespace has no such address), and send exited 0: the note was lost in silence.

No network beyond loopback: the browse is replaced; the node found is a socket of this test.
"""

from __future__ import annotations

import socket
from collections.abc import Iterator, Sequence

import pytest

import common.discovery
from batteur.tools import send
from common.discovery import NodeInfo
from common.messages import decode
from common.runtime import DEFAULT_BROWSE_ROLES
from tests.ports import free_port

pytestmark = pytest.mark.timeout(60)


@pytest.fixture
def node(monkeypatch: pytest.MonkeyPatch) -> Iterator[tuple[socket.socket, list[object]]]:
    """A node of every service role at one loopback socket, as discovery would list them; the browses asked."""
    receiver = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    receiver.bind(("127.0.0.1", free_port()))
    receiver.settimeout(10)
    port = receiver.getsockname()[1]
    asked: list[object] = []

    async def browse(timeout_s: float, interfaces: Sequence[str] | None = None) -> list[NodeInfo]:
        asked.append(interfaces)
        return [NodeInfo(role=role, node_id=f"{role}-1", host="127.0.0.1", port=port, protocol=1)
                for role in DEFAULT_BROWSE_ROLES]

    monkeypatch.setattr(common.discovery, "browse_nodes", browse)
    with receiver:
        yield receiver, asked


@pytest.mark.parametrize(("args", "to", "takes"), [
    (["/batteur/score/note", "1", "38", "100", "10"], "interaction", "physics"),
    (["/batteur/score/transport", "play", "0", "0"], "sound", "physics"),
    (["/batteur/physics/target", "right_hand", "1", "0.1", "0.3", "0.9", "0", "0", "0"], "graphics", "physics"),
    (["/batteur/sound/master", "-6", "0.2"], "physics", "sound"),
    (["/batteur/interaction/route/set", "127.0.0.1:9999", "*"], "sound", "interaction"),
    (["/batteur/graphics/latency", "0.1"], "interaction", "graphics"),
])
def test_a_control_to_a_role_that_ignores_it_is_refused(node: tuple[socket.socket, list[object]], args: list[str],
                                                        to: str, takes: str,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    _, asked = node
    assert send.main([*args, "--to", to]) == 2
    err = capsys.readouterr().err
    assert f"--to {takes}" in err and f"{to} nodes ignore it" in err, err
    assert asked == []  # refused before looking for nodes


@pytest.mark.parametrize(("args", "to"), [
    (["/batteur/score/note", "1", "38", "100", "10"], "physics"),  # the physics node plays scores
    (["/batteur/sound/master", "-6", "0.2"], "sound"),
    (["/batteur/subscribe", "/batteur/*", "1"], "interaction"),  # every node takes it
])
def test_a_message_to_a_role_that_takes_it_is_sent(node: tuple[socket.socket, list[object]], args: list[str],
                                                   to: str) -> None:
    receiver, _ = node
    assert send.main([*args, "--to", to]) == 0
    assert decode(receiver.recv(65535)).messages[0].ADDRESS == args[0]

