"""``batteur echo`` and ``batteur send --to ROLE`` browse where ``batteur ls`` does: ``--interface``, else the
interfaces in BATTEUR_INTERFACES (where a compose container's nodes announce), else loopback
(:func:`batteur.tools.nodes.browse_interfaces`), and their --help says so. Until 7 Dec only ls read the variable:
`docker compose exec graphics batteur echo '/batteur/*'` browsed the container's loopback and found no node.

No network: the browse is replaced, and finds nothing.
"""

from __future__ import annotations

from typing import Any

import pytest

import common.discovery
from batteur.tools import echo, ls, send

pytestmark = pytest.mark.timeout(60)


def _echo_browses(monkeypatch: pytest.MonkeyPatch, argv: list[str]) -> list[str] | None:
    seen: list[list[str] | None] = []

    async def find_targets(nodes: object, timeout_s: float, interfaces: list[str] | None) -> list[object]:
        seen.append(list(interfaces) if interfaces else None)
        return []

    monkeypatch.setattr(echo, "find_targets", find_targets)
    assert echo.main(["/batteur/*", "--browse", "0.1", *argv]) == 1  # no nodes found
    return seen[0]


def _send_browses(monkeypatch: pytest.MonkeyPatch, argv: list[str]) -> list[str] | None:
    seen: list[list[str] | None] = []

    async def browse_nodes(timeout_s: float, interfaces: list[str] | None = None) -> list[Any]:
        seen.append(list(interfaces) if interfaces else None)
        return []

    monkeypatch.setattr(common.discovery, "browse_nodes", browse_nodes)
    assert send.main(["/batteur/sound/master", "-6", "0.2", "--to", "sound", "--timeout", "0.1", *argv]) == 1
    return seen[0]


@pytest.mark.parametrize("browses", [_echo_browses, _send_browses], ids=["echo", "send"])
def test_the_tools_browse_batteur_interfaces_when_no_interface_is_given(
        browses: Any, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setenv("BATTEUR_INTERFACES", "eth0, 10.0.0.7")
    assert browses(monkeypatch, []) == ["eth0", "10.0.0.7"]
    assert "on eth0, 10.0.0.7 (BATTEUR_INTERFACES)" in capsys.readouterr().err  # where it looked
    assert browses(monkeypatch, ["--interface", "lo"]) == ["lo"]  # the flag wins
    monkeypatch.delenv("BATTEUR_INTERFACES")
    assert browses(monkeypatch, []) is None  # loopback, as before
    assert "on loopback" in capsys.readouterr().err


@pytest.mark.parametrize("tool", [ls, echo, send], ids=["ls", "echo", "send"])
def test_their_help_says_where_they_browse(tool: Any, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        tool.main(["--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "BATTEUR_INTERFACES" in text and "loopback" in text
