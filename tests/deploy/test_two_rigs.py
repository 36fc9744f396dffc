"""Two classes' rigs on one network, and a firewall that drops multicast (8 Dec walkthrough, docs/deployment.md).

Laptops are network namespaces on one bridge (or a veth pair); every node runs mDNS on its namespace's address only.
Namespaces share the machine's host name, as two classroom laptops imaged alike would; ``unshare --uts`` gives one
its own. Light nodes (the runtime around a core that does nothing, tests/test_runtime.py's node script) stand for
physics and sound where the test is about discovery and the clock, not about playing.

- the rig's node ids name the machine (and the port): two rigs on two machines both register, where until 8 Dec the
  second's discovery failed to start (the same ``ROLE-rig9101`` ids);
- a rig whose service's discovery failed to start says so in its ready line instead of "ready";
- a node that finds two clock masters warns once, naming both and the fix, and stays on the first;
- ``--rig NAME`` / ``BATTEUR_RIG``: nodes of another rig are ignored (no second master, no peer of it);
- a peer whose mDNS records expire unanswered (multicast dropped) but who still answers over unicast is kept, with one
  warning that discovery has gone quiet; one that stops answering altogether is dropped.
"""

from __future__ import annotations

import json
import re
import signal
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from batteur import rig as rig_module
from common.messages import PROTOCOL_VERSION
from tests.deploy.twohosts import wait_line
from tests.netns import Namespace, NetnsLab, NsProcess, netns_lab  # noqa: F401  (fixture)
from tests.test_runtime import NODE_SCRIPT

pytestmark = [pytest.mark.netns, pytest.mark.timeout(180)]

READY = re.compile(r"batteur rig: services up .*")


def _plan_ids(monkeypatch: pytest.MonkeyPatch, hostname: str, *argv: str) -> dict[str, str]:
    monkeypatch.setattr(rig_module.socket, "gethostname", lambda: hostname)
    opts = rig_module.build_parser().parse_args(["--services", "physics,interaction,sound,graphics", *argv])
    plans = rig_module.plan_rig(opts, 1000.0, environ={})
    return {plan.role: rig_module.option_values(plan.args, "--node-id")[-1] for plan in plans}


def test_rig_node_ids_name_the_machine_and_the_port(monkeypatch: pytest.MonkeyPatch) -> None:
    laptop_a = _plan_ids(monkeypatch, "laptop-a.school.lan")
    laptop_c = _plan_ids(monkeypatch, "laptop-c")
    second_rig_on_a = _plan_ids(monkeypatch, "laptop-a", "--base-port", "9201")
    assert laptop_a["sound"] == "sound-laptop-a-rig9101"
    assert not set(laptop_a.values()) & set(laptop_c.values())
    assert not set(laptop_a.values()) & set(second_rig_on_a.values())
    long_name = _plan_ids(monkeypatch, "x" * 80)
    assert all(len(node_id) <= 64 and node_id.endswith("-rig9101") for node_id in long_name.values())


def test_rig_node_ids_tell_two_classes_on_laptops_of_one_host_name_apart(monkeypatch: pytest.MonkeyPatch) -> None:
    """Laptops imaged alike (``ubuntu``), one rig per class: until 8 Dec both registered the same zeroconf names."""
    class1 = _plan_ids(monkeypatch, "ubuntu", "--rig", "class1")
    class2 = _plan_ids(monkeypatch, "ubuntu", "--rig", "class2")
    assert class1["physics"] == "physics-ubuntu-class1-rig9101"
    assert not set(class1.values()) & set(class2.values())
    monkeypatch.setattr(rig_module.socket, "gethostname", lambda: "ubuntu")
    opts = rig_module.build_parser().parse_args(["--services", "sound"])
    from_env = rig_module.plan_rig(opts, 1000.0, environ={"BATTEUR_RIG": "class2"})
    assert rig_module.option_values(from_env[0].args, "--node-id") == [class2["sound"]]
    assert _plan_ids(monkeypatch, "ubuntu")["sound"] == "sound-ubuntu-rig9101"  # the default rig: ids unchanged
    long_name = _plan_ids(monkeypatch, "x" * 80, "--rig", "r" * 32)
    assert all(len(node_id) <= 64 and node_id.endswith("-" + "r" * 32 + "-rig9101") for node_id in long_name.values())
    # host names of only non-ASCII characters, which used to all become "host"
    cyrillic, greek = _plan_ids(monkeypatch, "ноутбук"), _plan_ids(monkeypatch, "λάπτοπ")
    assert not set(cyrillic.values()) & set(greek.values())
    assert all(node_id.isascii() and len(node_id) <= 64 for node_id in cyrillic.values())


def test_rig_gives_its_name_to_every_service_and_refuses_one_for_a_service(monkeypatch: pytest.MonkeyPatch) -> None:
    opts = rig_module.build_parser().parse_args(["--services", "physics,sound", "--rig", "class2"])
    plans = rig_module.plan_rig(opts, 1000.0, environ={})
    assert all(rig_module.option_values(plan.args, "--rig") == ["class2"] for plan in plans)
    unnamed = rig_module.plan_rig(rig_module.build_parser().parse_args(["--services", "sound"]), 1000.0, environ={})
    assert rig_module.option_values(unnamed[0].args, "--rig") == []  # the service's BATTEUR_RIG, else the default
    with pytest.raises(SystemExit):
        rig_module.build_parser().parse_args(["--rig", "class 2"])
    with pytest.raises(rig_module.UsageError, match="--rig"):
        rig_module.plan_rig(rig_module.build_parser().parse_args(["--services", "sound", "--sound-arg", "--rig x"]),
                            1000.0, environ={})


def _rig(ns: Namespace, address: str, hostname: str | None = None) -> NsProcess:
    """``batteur rig`` with interaction alone (quick to start), zeroconf on ``address``; under its own host name if
    ``hostname`` is given (a UTS namespace: another laptop)."""
    argv = [sys.executable, "-m", "batteur", "rig", "--services", "interaction", "--interfaces", address]
    if hostname is None:
        return ns.popen(*argv)
    return ns.popen("unshare", "--uts", "sh", "-c", f'hostname {hostname} && exec "$0" "$@"', *argv)


def _stdout_line(proc: NsProcess, pattern: re.Pattern[str], timeout: float) -> str:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        for line in proc.lines:
            if pattern.search(line):
                return line
        if not proc._drain(0.2) and proc.popen.poll() is not None:
            break
    raise AssertionError(proc.describe(f"no line matching {pattern.pattern!r} within {timeout:g} s"))


def test_two_rigs_on_two_machines_are_two_sets_of_nodes_and_a_failed_discovery_is_said(
    netns_lab: NetnsLab,  # noqa: F811
) -> None:
    a, c, d = (netns_lab.namespace(tag) for tag in ("classA", "classC", "classD"))
    addr_a, addr_c, addr_d = netns_lab.bridge([a, c, d])
    first = _rig(a, addr_a)
    other_machine = _rig(c, addr_c, hostname="laptop-c")
    for proc in (first, other_machine):
        line = _stdout_line(proc, READY, 60)
        assert ": ready;" in line and "discovery" not in line, line
    # both rigs' nodes on the network, apart: until 8 Dec both were interaction-rig9101 (one name, one node listed,
    # and their peers' tables flipped between the two machines)
    listing = a.python("-m", "common.discovery", "ls", "--interface", addr_a, "--timeout", "3")
    assert listing.popen.wait(timeout=30) == 0
    nodes = [event for event in listing.events() if event.get("role") == "interaction"]
    assert sorted(node["host"] for node in nodes) == sorted([addr_a, addr_c]), nodes
    assert len({node["node_id"] for node in nodes}) == 2 and any("laptop-c" in node["node_id"] for node in nodes)
    # a laptop where mDNS cannot start (another program holds UDP 5353 alone): the rig does not say "ready"
    holder = d.python("-c", "import json, socket, time; s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM); "
                      "s.bind(('0.0.0.0', 5353)); print(json.dumps({'event': 'bound'}), flush=True); time.sleep(300)")
    holder.expect(lambda e: e.get("event") == "bound", timeout=20)
    line = _stdout_line(_rig(d, addr_d), READY, 60)
    assert "running, not ready" in line and "discovery (zeroconf) failed to start on interaction" in line, line
    assert ": ready;" not in line


def _node_script(tmp_path: Path) -> Path:
    script = tmp_path / "node.py"
    script.write_text(NODE_SCRIPT.replace('run_node("trivial"', "run_node(sys.argv.pop(1)"))
    return script


def _node(ns: Namespace, script: Path, role: str, node_id: str, address: str, *extra: str,
          env: dict[str, str] | None = None) -> NsProcess:
    return ns.python(str(script), role, "--node-id", node_id, "--host", "0.0.0.0", "--allow", "10.0.0.0/8",
                     "--interface", address, "--port", "9100", "--no-oscquery", "--log-level", "INFO", *extra,
                     env={"BATTEUR_RIG": "", **(env or {})})


def _count(proc: NsProcess, test: Callable[[str], bool]) -> int:
    return sum(1 for line in proc.errors if test(line))


def test_two_clock_masters_are_warned_of_once_and_another_rigs_are_ignored(
    netns_lab: NetnsLab, tmp_path: Path  # noqa: F811
) -> None:
    script = _node_script(tmp_path)
    one, two, three, four = (netns_lab.namespace(tag) for tag in ("phys1", "snd", "phys2", "phys3"))
    addr_one, addr_two, addr_three, addr_four = netns_lab.bridge([one, two, three, four])
    epoch = time.time()
    first = _node(one, script, "physics", "physics-one", addr_one, "--epoch", repr(epoch))
    sound = _node(two, script, "sound", "sound-one", addr_two, "--epoch", repr(epoch))
    wait_line(sound, lambda s: "rig clock synced to physics" in s, 30)
    # another class's physics, named apart (BATTEUR_RIG, as every node of its rig): ignored, no second master
    other_class = _node(four, script, "physics", "physics-class2", addr_four, "--epoch", repr(epoch - 400),
                        env={"BATTEUR_RIG": "class2"})
    wait_line(sound, lambda s: "ignoring physics-physics-class2" in s and "of rig 'class2'" in s, 30)
    # a second physics of the same (unnamed) rig 400 s apart: warned of, naming both and the fix, and not followed
    second = _node(three, script, "physics", "physics-two", addr_three, "--epoch", repr(epoch - 400))
    warning = wait_line(sound, lambda s: "clock masters" in s, 30)
    assert "physics-one" in warning and "physics-two" in warning and "--rig NAME" in warning, warning
    assert "follows physics-one" in warning and "physics-class2" not in warning, warning
    time.sleep(4.0)  # a few more pings and sweeps: a switch would step the rig clock by 400 s
    assert _count(sound, lambda s: "clock masters" in s) == 1, "\n".join(sound.errors)
    assert _count(sound, lambda s: "stepped" in s) == 0, "\n".join(sound.errors)
    assert _count(sound, lambda s: "peer physics physics-class2" in s) == 0, "\n".join(sound.errors)
    for proc in (first, second, other_class):
        assert proc.popen.poll() is None


def test_the_tools_find_the_nodes_of_their_rig(netns_lab: NetnsLab, tmp_path: Path) -> None:  # noqa: F811
    """Two classes on one network, each a physics node of its rig: ``ls`` lists, and ``send --to physics`` starts,
    the tool's rig's alone (``--rig`` / BATTEUR_RIG); until 8 Dec they saw both classes' nodes."""
    script = _node_script(tmp_path)
    one, two = netns_lab.namespace("rigone"), netns_lab.namespace("rigtwo")
    addr_one, addr_two = netns_lab.bridge([one, two])
    nodes = [_node(ns, script, "physics", f"physics-{rig}", address, env={"BATTEUR_RIG": rig})
             for ns, rig, address in ((one, "class1", addr_one), (two, "class2", addr_two))]
    for proc in nodes:
        wait_line(proc, lambda s: "discovery" in s.lower() or "running" in s.lower(), 30)

    def tool(*argv: str, rig: str | None) -> NsProcess:
        proc = one.python("-m", "batteur", *argv, "--interface", addr_one, env={"BATTEUR_RIG": rig or ""})
        proc.popen.wait(timeout=60)
        while proc._drain(0.2):
            pass
        return proc

    listing = tool("ls", "--json", rig="class1")
    rows = json.loads("\n".join(listing.lines))
    assert [(row["node_id"], row["rig"]) for row in rows] == [("physics-class1", "class1")], listing.lines
    assert "1 node(s) of other rigs (class2) left out" in "\n".join(listing.errors), listing.errors
    table = tool("ls", "--rig", "class2", rig="class1")  # the flag wins over the environment
    assert table.lines[0].split()[:3] == ["role", "rig", "node"], table.lines
    assert [line.split()[:3] for line in table.lines[1:]] == [["physics", "class2", "physics-class2"]], table.lines
    # a Hello from a tool: the node answers with its Health, which names it
    hello = ("/batteur/hello", "cli", "tool-send", str(PROTOCOL_VERSION), "0", "--to", "physics", "--replies", "2")
    sent = tool("send", *hello, rig="class1")
    answers = "\n".join(sent.lines)
    assert "physics-class1" in answers and "physics-class2" not in answers, sent.lines + sent.errors
    nobody = tool("send", *hello, "--rig", "class3", rig=None)
    assert nobody.popen.returncode == 1 and "other rigs (class1, class2) left out" in "\n".join(nobody.errors)
    for proc in nodes:
        assert proc.popen.poll() is None


def _drop_mdns(ns: Namespace) -> None:
    """A firewall in ``ns`` that drops mDNS (UDP 5353) both ways, and lets the nodes' unicast OSC through."""
    ns.run("nft", "add", "table", "inet", "btmdns")
    for chain, hook in (("in", "input"), ("out", "output")):
        ns.run("nft", "add", "chain", "inet", "btmdns", chain, f"{{ type filter hook {hook} priority 0 ; }}")
        ns.run("nft", "add", "rule", "inet", "btmdns", chain, "udp", "dport", "5353", "counter", "drop")


def test_a_peer_that_answers_over_unicast_is_kept_when_multicast_is_dropped(
    netns_lab: NetnsLab, tmp_path: Path  # noqa: F811
) -> None:
    script = _node_script(tmp_path)
    a, b = netns_lab.namespace("fwA"), netns_lab.namespace("fwB")
    addr_a, addr_b = netns_lab.veth(a, b)
    epoch = repr(time.time())
    physics = _node(a, script, "physics", "physics-fw", addr_a, "--epoch", epoch, "--discovery-ttl-s", "2")
    sound = _node(b, script, "sound", "sound-fw", addr_b, "--epoch", epoch, "--discovery-ttl-s", "2")
    wait_line(sound, lambda s: "rig clock synced to physics" in s, 30)
    wait_line(physics, lambda s: "found sound sound-fw" in s, 30)
    _drop_mdns(b)
    for proc in (sound, physics):  # records expire in 2 s, the re-query goes unanswered for 3 s
        warning = wait_line(proc, lambda s: "discovery has gone quiet" in s, 30)
        assert "--peer" in warning, warning
    time.sleep(12.0)  # past a re-query (every 10 s) and many sweeps
    for proc in (sound, physics):
        assert _count(proc, lambda s: "discovery: lost" in s or "stopped answering" in s) == 0, "\n".join(proc.errors)
        assert _count(proc, lambda s: "discovery has gone quiet" in s) == 1, "\n".join(proc.errors)
    start = len(sound.errors)
    physics.signal(signal.SIGKILL)  # gone for good, no goodbye (and none could pass): dropped after all
    wait_line(sound, lambda s: "discovery: lost physics-fw" in s and "unicast" in s, 30, start)
