"""Static peers (``--peer ROLE=HOST:PORT``): every one given for a role is sent to."""

from __future__ import annotations

from common.messages.system import ClockStatus
from common.peers import PeerTable, parse_static_peer


def test_two_static_peers_of_one_role_are_both_kept() -> None:
    # two sound servers (this laptop's and a Pd client): interaction sends every impact to both; the second
    # replaced the first, so one of them stayed silent
    table = PeerTable()
    for spec in ("sound=127.0.0.1:9103", "sound=[::1]:9203", "sound=127.0.0.1:9103"):  # the first one twice
        table.add(parse_static_peer(spec))
    assert sorted(p.address for p in table.for_role("sound")) == [("127.0.0.1", 9103), ("::1", 9203)]


def test_a_static_peers_id_names_it_and_fits_a_clock_status() -> None:
    peers = [parse_static_peer(spec) for spec in (
        "physics=127.0.0.1:9101", "physics=[fe80::1234:5678:9abc:def0]:65535",
        "physics=" + "a-very-long-host-name." * 10 + "example:9101")]
    assert peers[0].node_id == "static:physics:127.0.0.1:9101"
    assert len({p.node_id for p in peers}) == 3
    for peer in peers:  # the clock status names its master by this id (at most 64 characters, no brackets)
        ClockStatus.model_validate(dict(_status(), master=peer.node_id))


def _status() -> dict[str, object]:
    fields = ClockStatus.model_fields
    return {name: ("n" if name == "node_id" else "synced" if name == "state" else 0)
            for name in fields if fields[name].is_required()}
