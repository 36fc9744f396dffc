"""``batteur ls`` says where it browsed, and how to look elsewhere, with every list it prints, not only when it finds
nothing: a teacher's ``batteur ls`` without ``--interface`` listed the nodes on the rig laptop's loopback and left out
the sound laptop without a word.

No network: the browse is replaced by one that "finds" a Health answerer on loopback."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from batteur.tools import ls
from batteur.tools.nodes import Target
from common.messages import Health, encode
from tests.health_answerer import HealthAnswerer

pytestmark = pytest.mark.timeout(60)

HEALTH = Health(node_id="physics-rig9101", role="physics", protocol=1, time=12.5, rate_hz=1000.0,
                target_rate_hz=1000.0, overruns=0, messages_in=1, messages_out=1, dropped=0, dropped_malformed=0,
                dropped_unknown=0, dropped_type=0, dropped_range=0, dropped_other=0, late=0, peers=2)


@pytest.fixture
def browsed(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[list[str] | None]]:
    """Browsing "finds" one node (a Health answerer on loopback); yields the interfaces each browse was asked for."""
    node = HealthAnswerer(encode(HEALTH))
    seen: list[list[str] | None] = []

    async def find_targets(nodes: object, timeout_s: float, interfaces: list[str] | None) -> list[Target]:
        seen.append(list(interfaces) if interfaces else None)
        return [Target("127.0.0.1", node.port, "physics", "physics-rig9101", "127.0.0.1")]

    monkeypatch.setattr(ls, "find_targets", find_targets)
    monkeypatch.delenv("BATTEUR_INTERFACES", raising=False)
    yield seen
    node.close()


def test_a_list_browsed_on_loopback_says_so_and_how_to_see_other_machines(
        browsed: list[list[str] | None], capsys: pytest.CaptureFixture[str]) -> None:
    assert ls.main(["--browse", "0.1", "--timeout", "3"]) == 0
    out, err = capsys.readouterr()
    assert "physics-rig9101" in out  # the list, found
    said = " ".join(err.split())
    assert ("batteur ls: browsed on loopback only (127.0.0.1) for 0.1 s: nodes of other machines are not listed; "
            "to list them, browse on their network's interface: --interface eth0") in said, said


def test_a_list_browsed_on_named_interfaces_names_them_and_their_addresses(
        browsed: list[list[str] | None], capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("BATTEUR_INTERFACES", "lo")
    assert ls.main(["--browse", "0.2", "--timeout", "3", "--json"]) == 0
    out, err = capsys.readouterr()
    assert '"physics-rig9101"' in out and "browsed" not in out  # --json stays JSON
    assert browsed == [["lo"]]
    said = " ".join(err.split())
    assert "batteur ls: browsed on lo (127.0.0.1) (BATTEUR_INTERFACES) for 0.2 s; to look elsewhere: --interface" \
        in said, said


def test_nodes_given_by_address_are_not_said_to_be_browsed(capsys: pytest.CaptureFixture[str]) -> None:
    node = HealthAnswerer(encode(HEALTH))
    try:
        assert ls.main(["--node", f"127.0.0.1:{node.port}", "--timeout", "3"]) == 0
    finally:
        node.close()
    assert "browsed" not in capsys.readouterr().err
