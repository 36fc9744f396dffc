"""``batteur ls --json`` shows the whole of a node's Health that a user needs: the drops by reason (an OSC
walkthrough saw only the total ``dropped``) and the node's rig time (it could not learn what to stamp a timed
message with)."""

from __future__ import annotations

import json
from collections.abc import Iterator

import pytest

from batteur.tools import ls
from common.messages import Health, encode
from tests.health_answerer import HealthAnswerer

pytestmark = pytest.mark.timeout(60)

HEALTH = Health(node_id="sound-1", role="sound", protocol=1, time=1234.5678, rate_hz=187.5, target_rate_hz=187.5,
                overruns=0, messages_in=40, messages_out=3, dropped=15, dropped_malformed=1, dropped_unknown=2,
                dropped_type=3, dropped_range=4, dropped_other=5, late=0, peers=1)


@pytest.fixture
def node_port() -> Iterator[int]:
    """A UDP "node" on loopback that answers every Hello with :data:`HEALTH`."""
    node = HealthAnswerer(encode(HEALTH))
    yield node.port
    node.close()


def test_ls_json_gives_the_drops_by_reason_and_the_rig_time(node_port: int,
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    assert ls.main(["--node", f"127.0.0.1:{node_port}", "--timeout", "3", "--json"]) == 0
    row = json.loads(capsys.readouterr().out)[0]
    assert row["status"] == "ok" and row["dropped"] == 15
    by_reason = {k: row[k] for k in ("dropped_malformed", "dropped_unknown", "dropped_type", "dropped_range",
                                     "dropped_other")}
    assert by_reason == {"dropped_malformed": 1, "dropped_unknown": 2, "dropped_type": 3, "dropped_range": 4,
                         "dropped_other": 5}
    assert row["rig_time_s"] == pytest.approx(1234.568, abs=1e-3)  # a rig time's fraction is sent as float32


def test_ls_json_carries_every_health_field(node_port: int, capsys: pytest.CaptureFixture[str]) -> None:
    # a counter added to Health must reach the user too (wrong_node_unanswered did not, 7 Dec)
    assert ls.main(["--node", f"127.0.0.1:{node_port}", "--timeout", "3", "--json"]) == 0
    row = json.loads(capsys.readouterr().out)[0]
    assert set(Health.model_fields) - {"time"} <= set(row)  # the rig time is rig_time_s


def test_ls_help_says_what_the_json_adds(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        ls.main(["--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "dropped_range" in text and "rig_time_s" in text


def _browsed_interfaces(monkeypatch: pytest.MonkeyPatch, argv: list[str]) -> list[str] | None:
    """The interfaces ``batteur ls ARGV`` browses on (no network: the browse is replaced, and finds nothing)."""
    seen: list[list[str] | None] = []

    async def find_targets(nodes: object, timeout_s: float, interfaces: list[str] | None) -> list[object]:
        seen.append(list(interfaces) if interfaces else None)
        return []

    monkeypatch.setattr(ls, "find_targets", find_targets)
    assert ls.main(argv) == 1  # no nodes found
    return seen[0]


def test_ls_in_a_container_browses_where_its_nodes_announce(monkeypatch: pytest.MonkeyPatch,
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    """`docker compose exec graphics batteur ls`: the container's BATTEUR_INTERFACES (eth0, compose.yaml) is where
    the rig's nodes announce; until 7 Dec ls browsed loopback there and listed the one node of that container
    (on its eth0 address, heard through the shared mDNS socket), as if the other three were down."""
    monkeypatch.setenv("BATTEUR_INTERFACES", "eth0, 10.0.0.7")
    assert _browsed_interfaces(monkeypatch, []) == ["eth0", "10.0.0.7"]
    assert _browsed_interfaces(monkeypatch, ["--interface", "lo"]) == ["lo"]  # the flag wins
    assert "BATTEUR_INTERFACES" in capsys.readouterr().err  # the error names where it looked
    monkeypatch.delenv("BATTEUR_INTERFACES")
    assert _browsed_interfaces(monkeypatch, []) is None  # loopback, as before
