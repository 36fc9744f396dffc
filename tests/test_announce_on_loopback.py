"""A node that listens for other machines (``--host 0.0.0.0``, or a LAN address) but announces itself on loopback
only (no ``--interface``) warns at start, naming the fix: a teacher's sound laptop started with ``--host 0.0.0.0``
alone ran discovery on loopback, said so only in an INFO line (``on ['127.0.0.1']``) and a warning 30 s later, and
the rig laptop said ``no sound peer known`` once a minute. Every service, through the shared start-up
(``common.runtime.Node.start``).

In network namespaces (a veth gives each a LAN address); never on the host's interfaces."""

from __future__ import annotations

import sys
import time

import pytest

from tests.netns import NetnsLab, NsProcess

pytestmark = [pytest.mark.timeout(120), pytest.mark.netns]

WARNING = "but announces itself (zeroconf) on loopback only (127.0.0.1): nodes on other machines will not find it"
LISTENING = " Hz, clock "  # the node's start line ("... listening on ADDRESS (rate R Hz, clock ..."), after the warning


def _start(lab: NetnsLab, role: str, *flags: str) -> tuple[NsProcess, str]:
    """``batteur ROLE FLAGS`` in a namespace with a LAN address (a veth); the process and that address."""
    ns, other = lab.namespace(role[:5]), lab.namespace("other")
    lan, _ = lab.veth(ns, other)
    own = {"sound": ["--device", "none"], "graphics": ["--http-port", "0", "--no-oscquery"]}.get(role, [])
    proc = ns.popen("taskset", "-c", "0", sys.executable, "-m", "batteur", role, "--port", "0",
                    "--clock-master", "self", "--allow", "10.0.0.0/8", *own, *flags)
    return proc, lan


def _log_until(proc: NsProcess, text: str, timeout_s: float = 30.0) -> str:
    """The node's log (stderr) once it holds ``text``."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        log = "\n".join(proc.errors)
        if text in log:
            return log
        if proc.popen.poll() is not None:
            break
        time.sleep(0.1)
    raise AssertionError(proc.describe(f"no {text!r} in the log"))


@pytest.mark.parametrize("role", ["sound", "interaction", "graphics"])
def test_a_node_on_every_address_announcing_on_loopback_warns_with_the_fix(netns_lab: NetnsLab, role: str) -> None:
    proc, lan = _start(netns_lab, role, "--host", "0.0.0.0")
    log = _log_until(proc, LISTENING)
    said = [line for line in log.splitlines() if WARNING in line]
    assert len(said) == 1, log
    assert " WARNING " in said[0] and "this node listens on every address" in said[0]
    # the fix, with this machine's interface to give
    assert f"--interface NAME or ADDRESS (BATTEUR_INTERFACES; this machine's: veth0 ({lan}))" in said[0], said[0]


def test_a_node_on_a_lan_address_announcing_on_loopback_warns(netns_lab: NetnsLab) -> None:
    ns, other = netns_lab.namespace("lanad"), netns_lab.namespace("other")
    lan, _ = netns_lab.veth(ns, other)
    proc = ns.popen("taskset", "-c", "0", sys.executable, "-m", "batteur", "interaction", "--port", "0",
                    "--clock-master", "self", "--allow", "10.0.0.0/8", "--host", lan)
    log = _log_until(proc, LISTENING)
    assert f"this node listens on {lan} {WARNING}" in log, log


def test_a_node_announcing_on_its_lan_interface_does_not_warn(netns_lab: NetnsLab) -> None:
    ns, other = netns_lab.namespace("named"), netns_lab.namespace("other")
    lan, _ = netns_lab.veth(ns, other)
    proc = ns.popen("taskset", "-c", "0", sys.executable, "-m", "batteur", "sound", "--port", "0", "--device", "none",
                    "--clock-master", "self", "--allow", "10.0.0.0/8", "--host", "0.0.0.0", "--interface", lan)
    log = _log_until(proc, LISTENING)
    assert "announces itself" not in log, log
