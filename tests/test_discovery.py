"""Discovery: address choice and TXT validation without a network; zeroconf between processes
inside network namespaces the tests create (never on the host's interfaces)."""

from __future__ import annotations

import ipaddress
import signal
import sys
import time
from collections.abc import Iterator
from typing import Any

import pytest
from zeroconf.asyncio import AsyncServiceInfo

from common.discovery import (
    SERVICE_TYPE,
    Discovery,
    DiscoveryError,
    Rejection,
    ServiceTxt,
    choose_address,
    instance_name,
    is_loopback,
    parse_networks,
    peer_from_service,
    resolve_interfaces,
)
from common.messages.system import PROTOCOL_VERSION
from common.peers import Peer, PeerTable, parse_static_peer
from tests.netns import (
    Namespace,
    NetnsLab,
    NsProcess,
    list_namespaces,
    require_netns,
)

TXT = {"role": "sound", "proto": str(PROTOCOL_VERSION), "node_id": "snd-1", "port": "9000"}

# --------------------------------------------------------------------------- without a network


def test_loopback_addresses_are_recognised() -> None:
    assert is_loopback("127.0.0.1") and is_loopback("127.3.2.1") and is_loopback("::1")
    assert is_loopback("::ffff:127.0.0.1")
    assert not is_loopback("10.0.0.1") and not is_loopback("fe80::1%2") and not is_loopback("not-an-ip")


def test_lan_peers_never_get_a_loopback_address() -> None:
    announced = ["127.0.0.1", "::1", "10.1.2.3", "fd00::5"]
    assert choose_address(announced, allow_loopback=False) == "10.1.2.3"
    assert choose_address(["::1", "fd00::5", "127.0.0.1"], allow_loopback=False) == "fd00::5"
    assert choose_address(["127.0.0.1", "::1"], allow_loopback=False) is None


def test_loopback_preferred_when_on_loopback() -> None:
    assert choose_address(["10.1.2.3", "::1", "127.0.0.1"], allow_loopback=True) == "127.0.0.1"
    assert choose_address(["10.1.2.3", "::1"], allow_loopback=True) == "::1"
    assert choose_address(["10.1.2.3"], allow_loopback=True) == "10.1.2.3"


def test_address_in_our_network_preferred() -> None:
    nets = [ipaddress.ip_network("10.9.0.0/24")]
    assert choose_address(["192.168.1.4", "10.9.0.7"], allow_loopback=False, networks=nets) == "10.9.0.7"
    assert choose_address(["192.168.1.4", "10.9.0.7"], allow_loopback=False) == "192.168.1.4"
    assert choose_address(["0.0.0.0", "224.0.0.251"], allow_loopback=True) is None


def test_peer_from_service_reads_the_txt_record() -> None:
    peer = peer_from_service("sound-snd-1._osc._udp.local.", 9000, TXT, ["127.0.0.1", "10.0.0.2"],
                             allow_loopback=False)
    assert peer == Peer(role="sound", host="10.0.0.2", port=9000, node_id="snd-1", protocol=PROTOCOL_VERSION)


def test_peer_with_another_protocol_is_rejected() -> None:
    result = peer_from_service("x", 9000, {**TXT, "proto": str(PROTOCOL_VERSION + 1)}, ["10.0.0.2"],
                               allow_loopback=False)
    assert isinstance(result, Rejection) and result.reason == "protocol" and result.node_id == "snd-1"


@pytest.mark.parametrize(
    "txt",
    [
        {k: v for k, v in TXT.items() if k != "role"},
        {**TXT, "proto": "one"},
        {**TXT, "role": "Sound!"},
        {**TXT, "node_id": "has space"},
        {**TXT, "port": "70000"},
        {},
    ],
)
def test_bad_txt_records_are_rejected(txt: dict[str, str]) -> None:
    result = peer_from_service("x", 9000, txt, ["10.0.0.2"], allow_loopback=False)
    assert isinstance(result, Rejection) and result.reason == "txt"


def test_lan_peer_announcing_only_loopback_is_rejected() -> None:
    result = peer_from_service("x", 9000, TXT, ["127.0.0.1", "::1"], allow_loopback=False)
    assert isinstance(result, Rejection) and result.reason == "address"


def test_allow_list_rejects_peers_elsewhere() -> None:
    allowed = parse_networks(["10.0.0.0/24", "192.168.1.7"])
    assert isinstance(peer_from_service("x", 9000, TXT, ["10.0.0.2"], allow_loopback=False, allowed=allowed), Peer)
    result = peer_from_service("x", 9000, TXT, ["10.0.1.2"], allow_loopback=False, allowed=allowed)
    assert isinstance(result, Rejection) and result.reason == "not_allowed"
    with pytest.raises(DiscoveryError):
        parse_networks(["10.0.0.0/33"])


def test_srv_port_wins_over_txt_port() -> None:
    peer = peer_from_service("x", 9100, TXT, ["127.0.0.1"], allow_loopback=True)
    assert isinstance(peer, Peer) and peer.port == 9100


def test_txt_round_trip() -> None:
    txt = ServiceTxt(role="graphics", proto=3, node_id="g:1.a", port=7000)
    assert ServiceTxt.from_properties(txt.to_properties()) == txt


def test_instance_names_fit_in_a_dns_label() -> None:
    name = instance_name("interaction", "x" * 64)
    label = name[: -len(SERVICE_TYPE) - 1]
    assert name.endswith("." + SERVICE_TYPE) and len(label.encode()) <= 63 and "." not in label
    assert instance_name("sound", "a.b:c") == "sound-a-b-c._osc._udp.local."
    assert instance_name("sound", "x" * 64) != instance_name("sound", "x" * 63 + "y")


def test_interfaces_default_to_loopback_and_reject_wildcards() -> None:
    assert resolve_interfaces(None) == ["127.0.0.1"]
    assert resolve_interfaces(["lo"]) == ["127.0.0.1"]
    assert resolve_interfaces(["127.0.0.1", "lo"]) == ["127.0.0.1"]
    for bad in (["0.0.0.0"], ["::"], [], ["no-such-if0"], ["203.0.113.77"]):
        with pytest.raises(DiscoveryError):
            resolve_interfaces(bad)


def _info(node_id: str, port: int, addresses: list[str], role: str = "sound") -> AsyncServiceInfo:
    txt = ServiceTxt(role=role, proto=PROTOCOL_VERSION, node_id=node_id, port=port).to_properties()
    return AsyncServiceInfo(SERVICE_TYPE, instance_name(role, node_id), port=port, properties=txt,
                            server=f"{node_id}.local.", parsed_addresses=addresses)


def test_resolved_services_update_the_peer_table_without_network() -> None:
    """Role filter, own service ignored, static override, restart on the same address replaces."""
    table = PeerTable()
    events: list[tuple[str, str]] = []
    table.listeners.append(lambda kind, peer: events.append((kind, peer.node_id)))
    disc = Discovery("interaction", "me", 9500, None, table, ["sound"], allow_loopback=True)
    for info in (_info("me", 9500, ["127.0.0.1"], role="interaction"),  # ourselves
                 _info("gfx", 9600, ["127.0.0.1"], role="graphics"),  # a role we do not send to
                 _info("s1", 9000, ["127.0.0.1"])):
        disc._apply(info.name, info)
    assert [p.node_id for p in table.all()] == ["s1"]
    # the same node moves to another port: updated in place
    moved = _info("s1", 9001, ["127.0.0.1"])
    disc._apply(moved.name, moved)
    assert table.for_role("sound")[0].port == 9001 and disc.stats.updated == 1
    # a new node id on the same host:port (restart after a crash): the stale one goes
    fresh = _info("s2", 9001, ["127.0.0.1"])
    disc._apply(fresh.name, fresh)
    assert [p.node_id for p in table.for_role("sound")] == ["s2"]
    # a static peer overrides discovered ones for its role
    static = parse_static_peer("sound=10.9.9.9:9000")
    table.add(static)
    assert table.for_role("sound") == [static]
    assert ("added", "s1") in events and ("removed", "s1") in events and ("added", "s2") in events


def test_a_crashed_node_in_the_cache_does_not_swap_back_its_successor_on_the_same_address() -> None:
    """s1 crashes, s2 starts on the same host:port. Each sweep re-reads s1's unexpired records from the cache
    (up to ttl_s after the crash): s2, whose records came later, stays. Until 7 Dec the two swapped at every
    sweep until s1's records expired, each swap a 'found' log line and a Hello (a clock master's: an estimator
    reset). A node whose records are the fresher again (a fixed node id started anew there) wins it back."""
    table = PeerTable()
    disc = Discovery("interaction", "me", 9500, None, table, ["sound"], allow_loopback=True)
    old, new = _info("s1", 9000, ["127.0.0.1"]), _info("s2", 9000, ["127.0.0.1"])
    disc._apply(old.name, old, received_ms=1_000.0)
    disc._apply(new.name, new, received_ms=9_000.0)  # s2 announces itself: it replaces s1
    events: list[tuple[str, str]] = []
    table.listeners.append(lambda kind, peer: events.append((kind, peer.node_id)))
    for _ in range(3):  # sweeps, from the cache, in either order
        disc._apply(new.name, new, received_ms=9_000.0)
        disc._apply(old.name, old, received_ms=1_000.0)
    assert [p.node_id for p in table.for_role("sound")] == ["s2"] and events == []
    # s1's id comes back on that address with fresh records (a node started with --node-id s1): it is the live one
    disc._apply(old.name, old, received_ms=20_000.0)
    assert [p.node_id for p in table.for_role("sound")] == ["s1"]


def test_node_on_loopback_only_accepts_loopback_peers() -> None:
    table = PeerTable()
    disc = Discovery("interaction", "me", 9500, None, table, ["sound"])
    disc._addresses = ["127.0.0.1"]  # what start() resolves for the default interfaces
    lan = _info("lan", 9000, ["192.168.1.20"])
    disc._apply(lan.name, lan)
    local = _info("local", 9001, ["10.1.1.1", "127.0.0.1"])
    disc._apply(local.name, local)
    assert [(p.node_id, p.host) for p in table.all()] == [("local", "127.0.0.1")]
    assert disc.stats.rejected_not_allowed == 1


def test_discovery_rejects_bad_arguments() -> None:
    with pytest.raises(ValueError):
        Discovery("Bad Role", "n1", 9000, None, PeerTable(), ["sound"])
    with pytest.raises(ValueError):
        Discovery("sound", "n1", 0, None, PeerTable(), ["sound"])
    with pytest.raises(ValueError):
        Discovery("sound", "n1", 9000, None, PeerTable(), ["sound"], host_addresses=["host.example"])
    with pytest.raises(DiscoveryError):
        Discovery("sound", "n1", 9000, None, PeerTable(), ["sound"], allowed=["not-a-network"])


# --------------------------------------------------------------------------- inside namespaces

@pytest.fixture
def netns_lab() -> Iterator[NetnsLab]:
    require_netns()
    with NetnsLab() as lab:
        yield lab


START_TIMEOUT_S = 15.0
"""Generous: a process start is a Python import plus about 1 s of mDNS probing, on a busy machine."""


def run_node(ns: Namespace, role: str, node_id: str, port: int, *extra: str) -> NsProcess:
    return ns.python("-m", "common.discovery", "run", "--role", role, "--node-id", node_id, "--port", str(port),
                     "--check-interval", "0.5", "--resolve-timeout", "1", "--retry-interval", "1", *extra)


def is_event(kind: str, **peer: Any) -> Any:
    def match(event: dict[str, Any]) -> bool:
        return event.get("event") == kind and all(event.get("peer", {}).get(k) == v for k, v in peer.items())

    return match


def all_of(*checks: Any) -> Any:
    """A predicate true once every check has matched some event (in any order)."""
    pending = list(checks)

    def match(event: dict[str, Any]) -> bool:
        pending[:] = [check for check in pending if not check(event)]
        return not pending

    return match


@pytest.mark.netns
def test_register_find_lose_and_find_again(netns_lab: NetnsLab) -> None:
    ns = netns_lab.namespace("disc")
    b = run_node(ns, "interaction", "inter-1", 9100, "--browse", "sound")
    a = run_node(ns, "sound", "snd-1", 9000)
    found = b.expect(is_event("added", node_id="snd-1"), START_TIMEOUT_S)
    assert found["peer"] == {"role": "sound", "host": "127.0.0.1", "port": 9000, "node_id": "snd-1",
                             "protocol": PROTOCOL_VERSION, "static": False}

    # A stops cleanly: goodbye packets, B drops it
    a.signal(signal.SIGTERM)
    assert a.wait() == 0
    removed = b.expect(is_event("removed", node_id="snd-1"), 5.0)
    assert removed["for_role"] == {"sound": []}

    # A comes back with the same node id on a new port: found again, B never restarted.
    # Meanwhile a node speaking another protocol version is reported and never added.
    a = run_node(ns, "sound", "snd-1", 9001, "--ttl", "2")
    c = run_node(ns, "sound", "snd-old", 9003, "--proto", str(PROTOCOL_VERSION + 1))
    b.expect(all_of(is_event("added", node_id="snd-1", port=9001),
                    lambda e: e.get("event") == "rejected" and e.get("node_id") == "snd-old"), START_TIMEOUT_S)
    rejected = [e for e in b.events() if e.get("event") == "rejected"]
    assert [(e["node_id"], e["reason"]) for e in rejected] == [("snd-old", "protocol")]

    # A stalls (SIGSTOP) past its 2 s TTL: dropped; it resumes: found again without announcing
    a.expect(is_event("started"), 5.0)
    a.signal(signal.SIGSTOP)
    b.expect(is_event("removed", node_id="snd-1"), 10.0)
    a.signal(signal.SIGCONT)
    b.expect(is_event("added", node_id="snd-1", port=9001), 10.0)

    # A crashes (no goodbye): B drops it once its 2 s records expire unanswered.
    # A new process with a new node id is found meanwhile.
    a.kill()
    killed = time.monotonic()
    run_node(ns, "sound", "snd-2", 9002)
    b.expect(all_of(is_event("removed", node_id="snd-1"), is_event("added", node_id="snd-2", port=9002)),
             START_TIMEOUT_S)
    lost_after_s = time.monotonic() - killed

    # batteur ls: every node, every protocol version, TXT fields intact
    ls = ns.python("-m", "common.discovery", "ls", "--timeout", "3")
    assert ls.wait(timeout=15.0) == 0, ls.describe("ls failed")
    listed = {e["node_id"]: e for e in ls.events()}
    assert set(listed) == {"inter-1", "snd-2", "snd-old"}, ls.describe("unexpected nodes")
    assert listed["snd-old"]["protocol"] == PROTOCOL_VERSION + 1 and listed["snd-2"]["port"] == 9002
    assert listed["inter-1"]["role"] == "interaction" and listed["inter-1"]["host"] == "127.0.0.1"

    c.stop()
    b.stop()
    events = b.events()
    assert {e["peer"]["node_id"] for e in events if e.get("event") == "added"} == {"snd-1", "snd-2"}
    stats = events[-1]["stats"]
    assert stats["rejected_protocol"] == 1 and stats["lost"] == 3 and stats["found"] == 4
    print(f"crashed node dropped {lost_after_s:.1f} s after the kill (TTL 2 s, resolve timeout 1 s)")


@pytest.mark.netns
def test_a_node_started_on_the_address_of_a_crashed_one_stays_its_peer(netns_lab: NetnsLab) -> None:
    """A sound node crashes and a new one (new node id) takes its port, as a container restarted by compose
    does. The dead node's records stay in the observer's cache for their 30 s TTL, and the observer re-reads
    them at every check (0.5 s here): the dead node must not come back. Until 7 Dec the two swapped at each
    check until those records expired."""
    ns = netns_lab.namespace("swap")
    b = run_node(ns, "interaction", "inter-w", 9100, "--browse", "sound")
    dead = run_node(ns, "sound", "snd-dead", 9000)  # the default 30 s TTL
    b.expect(is_event("added", node_id="snd-dead"), START_TIMEOUT_S)
    dead.kill()
    run_node(ns, "sound", "snd-live", 9000)
    b.expect(is_event("added", node_id="snd-live"), START_TIMEOUT_S)
    time.sleep(5.0)  # ten checks of the cache, the dead node's records still in it
    added = [e["peer"]["node_id"] for e in b.events() if e.get("event") == "added"]
    assert added == ["snd-dead", "snd-live"], b.describe("the dead node came back")


@pytest.mark.netns
def test_static_peer_overrides_discovery_for_its_role(netns_lab: NetnsLab) -> None:
    ns = netns_lab.namespace("static")
    b = run_node(ns, "interaction", "inter-s", 9100, "--browse", "sound", "--peer", "sound=10.99.0.1:9999")
    a = run_node(ns, "sound", "snd-s", 9000, "--extra", "_oscjson._tcp.local.:8080")
    found = b.expect(is_event("added", node_id="snd-s"), START_TIMEOUT_S)
    assert found["peer"]["host"] == "127.0.0.1"  # discovered and in the table...
    # ...but the static peer wins
    assert [p["node_id"] for p in found["for_role"]["sound"]] == ["static:sound:10.99.0.1:9999"]

    # the extra service (OSCQuery's _oscjson._tcp) is registered next to _osc._udp
    a.expect(is_event("started"), START_TIMEOUT_S)
    probe = ns.python("-c", RESOLVE_EXTRA)
    assert probe.wait(timeout=15.0) == 0, probe.describe("resolve failed")
    assert probe.events() == [{"ok": True, "port": 8080, "txt": {"role": "sound", "node_id": "snd-s"}}]


RESOLVE_EXTRA = """
import asyncio, json
from zeroconf import DNSQuestionType
from zeroconf.asyncio import AsyncServiceInfo, AsyncZeroconf

async def main():
    async with AsyncZeroconf(interfaces=["127.0.0.1"]) as zc:
        info = AsyncServiceInfo("_oscjson._tcp.local.", "sound-snd-s._oscjson._tcp.local.")
        ok = await info.async_request(zc.zeroconf, 5000, question_type=DNSQuestionType.QM)
        print(json.dumps({"ok": ok, "port": info.port, "txt": info.decoded_properties}))

asyncio.run(main())
"""


@pytest.mark.netns
def test_lan_peers_across_a_bridge_get_their_lan_address(netns_lab: NetnsLab) -> None:
    """Two 'machines' on one Ethernet segment; the sender also announces 127.0.0.1, which is filtered."""
    one, two = netns_lab.namespace("host1"), netns_lab.namespace("host2")
    addr_one, addr_two = netns_lab.bridge([one, two])
    b = run_node(two, "interaction", "inter-lan", 9100, "--browse", "sound", "--interface", addr_two)
    hidden = run_node(one, "sound", "snd-lo", 9001)  # loopback only: must stay invisible from two
    run_node(one, "sound", "snd-lan", 9000, "--interface", "veth0", "--ttl", "2",
             "--host-address", "127.0.0.1", "--host-address", addr_one)
    found = b.expect(is_event("added", node_id="snd-lan"), START_TIMEOUT_S)
    assert found["peer"]["host"] == addr_one
    hidden.expect(is_event("started"), START_TIMEOUT_S)

    # the cable is pulled past the sender's 2 s TTL: dropped; plugged back: found again by
    # re-asking (the sender does not announce again, and queries sent meanwhile were lost)
    one.ip("link", "set", "veth0", "down")
    b.expect(is_event("removed", node_id="snd-lan"), 10.0)
    one.ip("link", "set", "veth0", "up")
    b.expect(is_event("added", node_id="snd-lan"), 10.0)
    assert all(e.get("peer", {}).get("node_id") != "snd-lo" for e in b.events())


@pytest.mark.netns
def test_netns_helpers_link_namespaces_and_clean_up() -> None:
    require_netns()
    with NetnsLab() as lab:
        a, b = lab.namespace("a"), lab.namespace("b")
        addr_a, addr_b = lab.veth(a, b)
        assert a.run("ip", "-o", "addr", "show", "veth0").stdout.count(addr_a) == 1
        flags = a.run("ip", "-o", "link", "show", "lo").stdout
        assert "MULTICAST" in flags and "UP" in flags
        probe = f"import socket; socket.create_connection(('{addr_b}', 9), timeout=2)"
        result = a.run(sys.executable, "-c", probe, check=False)
        assert "ConnectionRefusedError" in result.stderr, result.stderr  # b's kernel answered over the veth
        names = {ns.name for ns in lab.namespaces}
        assert names <= list_namespaces()
    assert not names & list_namespaces()
