"""``batteur send --to ROLE`` browses for its nodes as long as ``batteur ls`` and ``batteur echo`` do by default, and
takes their ``--browse SECONDS``. Until 7 Dec it browsed 2 s (its ``--timeout``) where they browse 3 s, and missed
the physics node of a loaded rig that ls listed.

No network: the browse is replaced; it finds nothing, or a node of each role at one socket of this test.
"""

from __future__ import annotations

import socket
from collections.abc import Iterator, Sequence

import pytest

import common.discovery
from batteur.tools import echo, ls, nodes, send
from common.discovery import NodeInfo
from common.messages import decode
from common.runtime import DEFAULT_BROWSE_ROLES
from tests.ports import free_port

pytestmark = pytest.mark.timeout(60)

MASTER = ["/batteur/sound/master", "-6", "0.2"]


@pytest.fixture
def browsed(monkeypatch: pytest.MonkeyPatch) -> list[float]:
    """How long each browse was asked to last, seconds (it finds nothing)."""
    asked: list[float] = []

    async def browse(timeout_s: float, interfaces: Sequence[str] | None = None) -> list[NodeInfo]:
        asked.append(timeout_s)
        return []

    monkeypatch.setattr(common.discovery, "browse_nodes", browse)
    return asked


def test_send_browses_as_long_as_ls_and_echo_by_default(browsed: list[float],
                                                         capsys: pytest.CaptureFixture[str]) -> None:
    assert ls.main([]) == 1 and echo.main(["/batteur/*"]) == 1  # no nodes found
    assert send.main([*MASTER, "--to", "sound"]) == 1
    assert browsed == [nodes.BROWSE_S] * 3
    assert f"no sound node found on loopback (--interface eth0, say, for the nodes of a LAN or a compose network) " \
           f"within {nodes.BROWSE_S:g} s" in capsys.readouterr().err


def test_send_takes_the_browse_option_of_ls_and_echo(browsed: list[float]) -> None:
    assert send.main([*MASTER, "--to", "sound", "--browse", "0.25"]) == 1
    assert ls.main(["--browse", "0.25"]) == 1 and echo.main(["/batteur/*", "--browse", "0.25"]) == 1
    assert browsed == [0.25] * 3
    assert send.main([*MASTER, "--to", "sound", "--timeout", "0.5"]) == 1  # the wait for a rig time, not the browse
    assert browsed[-1] == nodes.BROWSE_S


@pytest.mark.parametrize("bad", ["0", "-1", "nan", "soon"])
def test_a_browse_that_is_no_duration_is_refused(bad: str, browsed: list[float]) -> None:
    with pytest.raises(SystemExit) as exit_:
        send.main([*MASTER, "--to", "sound", "--browse", bad])
    assert exit_.value.code == 2 and browsed == []


@pytest.fixture
def every_role_at_one_socket(monkeypatch: pytest.MonkeyPatch) -> Iterator[socket.socket]:
    receiver = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    receiver.bind(("127.0.0.1", free_port()))
    receiver.settimeout(10)
    port = receiver.getsockname()[1]

    async def browse(timeout_s: float, interfaces: Sequence[str] | None = None) -> list[NodeInfo]:
        return [NodeInfo(role=role, node_id=f"{role}-1", host="127.0.0.1", port=port, protocol=1)
                for role in DEFAULT_BROWSE_ROLES]

    monkeypatch.setattr(common.discovery, "browse_nodes", browse)
    with receiver:
        yield receiver


@pytest.mark.parametrize("role", ["sound", "graphics"])
def test_send_finds_the_nodes_of_its_role(every_role_at_one_socket: socket.socket, role: str) -> None:
    args = MASTER if role == "sound" else ["/batteur/graphics/latency", "0.1"]
    assert send.main([*args, "--to", role, "--browse", "0.25"]) == 0
    assert decode(every_role_at_one_socket.recv(65535)).messages[0].ADDRESS == args[0]
