"""The network tools as a user at a terminal meets them: `batteur ls`, `batteur echo`, `batteur send` and
`python -m common.discovery` given bad arguments, silent or hostile nodes, an IPv6 node, a pipe into `head`,
Ctrl-C. Nodes are fakes on loopback (no discovery); zeroconf runs only inside network namespaces."""

from __future__ import annotations

import asyncio
import json
import logging
import os
import signal
import socket
import subprocess
import sys
import threading
import urllib.request
from collections.abc import Iterator, Sequence
from pathlib import Path

import pytest

from batteur.tools import echo, ls, send
from common.discovery import Discovery, NodeInfo
from common.messages import Health, Hello, OscMessage, Subscribe, decode, encode
from common.messages.base import MessageError
from common.oscquery import OscQueryServer
from tests.netns import Namespace, NetnsLab, require_netns
from tests.ports import free_port

REPO = Path(__file__).resolve().parents[1]


def health(node_id: str = "fake-1", rate_hz: float = 250.0) -> Health:
    return Health(node_id=node_id, role="sound", protocol=1, time=1.5, rate_hz=rate_hz, target_rate_hz=250.0,
                  overruns=0, messages_in=1, messages_out=1, dropped=0, dropped_malformed=0, dropped_unknown=0,
                  dropped_type=0, dropped_range=0, dropped_other=0, late=0, peers=0, decode_unanswered=7,
                  replies_unanswered=5)


class FakeNode:
    """A UDP "node": answers a Hello with garbage, then a Health; once subscribed to, sends ``stream`` to the
    subscriber over and over (as a node copies the messages it sees)."""

    def __init__(self, host: str = "127.0.0.1", port: int = 0, stream: Sequence[OscMessage] = (),
                 node_id: str = "fake-1") -> None:
        family = socket.AF_INET6 if ":" in host else socket.AF_INET
        self.sock = socket.socket(family, socket.SOCK_DGRAM)
        self.sock.bind((host, port))
        self.sock.settimeout(0.05)
        self.port: int = self.sock.getsockname()[1]
        self.stream = [encode(m) for m in stream]
        self.node_id = node_id
        self.subscribers: set[tuple[str, int]] = set()
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        while not self.stop.is_set():
            try:
                data, source = self.sock.recvfrom(65535)
            except TimeoutError:
                data = b""
            except OSError:
                return
            if data:
                self._answer(data, source[:2])
            for subscriber in list(self.subscribers):
                for packet in self.stream:
                    self.sock.sendto(packet, subscriber)

    def _answer(self, data: bytes, source: tuple[str, int]) -> None:
        try:
            messages = decode(data).messages
        except MessageError:
            return
        for message in messages:
            if isinstance(message, Hello):  # hostile first: junk and a huge datagram, then a Health with odd values
                self.sock.sendto(b"\x00garbage", source)
                self.sock.sendto(b"/batteur/health\x00" + b"\xff" * 60_000, source)
                self.sock.sendto(encode(health(self.node_id, rate_hz=3.4e38)), source)
            elif isinstance(message, Subscribe):
                self.subscribers.add(source)

    def close(self) -> None:
        self.stop.set()
        self.thread.join(timeout=5)
        self.sock.close()


@pytest.fixture
def fake_node() -> Iterator[FakeNode]:
    node = FakeNode(stream=[Hello(role="cli", node_id="seen", protocol=1, osc_port=9), health("other")])
    yield node
    node.close()


def child_takes_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)  # background suites ignore SIGINT, children inherit that


def batteur(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-m", "batteur", *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, cwd=REPO, preexec_fn=child_takes_sigint)


# --------------------------------------------------------------------------- send


@pytest.mark.parametrize(("args", "says"), [
    (["--raw", "x", "1"], "is not an OSC address"),  # was sent: no node can match an address without '/'
    (["--raw", "/a b", "1"], "no ' '"),
    (["--raw", "/x*", "1"], "no '*'"),  # a pattern, not an address
    (["--raw", "/x/", "1"], "is not an OSC address"),
    (["--raw", "/x", "1e40"], "does not fit its OSC type"),  # was an OverflowError traceback
    (["--raw", "/x", "99999999999"], "does not fit its OSC type"),  # was a BuildError traceback
    (["/batteur/contact", "1", "0.5", "3", "snare", "tip", "1e39", *["0"] * 7, "1", "0", "0", "0"],
     "x: beyond a 32-bit float"),  # a finite value float32 cannot hold: refused with the message's model
])
def test_send_refuses_what_osc_cannot_carry_in_one_line(args: list[str], says: str,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    receiver = FakeNode()
    try:
        assert send.main([*args, "--to", f"127.0.0.1:{receiver.port}"]) == 2
        err = capsys.readouterr().err
        assert says in err and len(err.strip().splitlines()) == 1
    finally:
        receiver.close()


def test_send_to_is_an_address_or_a_role_looked_up_on_the_given_interface(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    import common.discovery

    asked: list[object] = []
    receiver = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    receiver.bind(("127.0.0.1", 0))
    receiver.settimeout(10)
    port = receiver.getsockname()[1]

    async def browse(timeout_s: float, interfaces: Sequence[str] | None = None) -> list[NodeInfo]:
        asked.append(interfaces)
        return [NodeInfo(role="graphics", node_id="g1", host="127.0.0.1", port=port, protocol=1)]

    monkeypatch.setattr(common.discovery, "browse_nodes", browse)
    with receiver:
        # neither HOST:PORT nor a role: refused before browsing (was a 2 s browse and "no node found")
        assert send.main(["/batteur/graphics/latency", "0.1", "--to", "my.host"]) == 2
        assert "neither HOST:PORT nor a role" in capsys.readouterr().err and asked == []
        # a role on a chosen interface (there was no --interface: a LAN rig could not be reached by role)
        assert send.main(["/batteur/graphics/latency", "0.1", "--to", "graphics", "--interface", "10.0.0.1"]) == 0
        assert asked == [["10.0.0.1"]]
        assert decode(receiver.recv(65535)).messages[0].ADDRESS == "/batteur/graphics/latency"
        assert send.main(["/batteur/sound/level", "snare", "-6", "--to", "sound"]) == 1
        err = capsys.readouterr().err
        assert "no sound node found" in err and "roles found: graphics" in err


# --------------------------------------------------------------------------- ls


def test_ls_names_a_bad_or_unresolvable_node_in_one_line(monkeypatch: pytest.MonkeyPatch,
                                                         capsys: pytest.CaptureFixture[str]) -> None:
    assert ls.main(["--node", "garbage", "--timeout", "1"]) == 2
    assert "--node 'garbage' is not HOST:PORT" in capsys.readouterr().err  # was "peer 'node=garbage': ROLE=..."
    # refused before zeroconf opens a socket (was a DiscoveryError traceback)
    assert ls.main(["--interface", "no-such-if0", "--browse", "1"]) == 2
    assert "interface 'no-such-if0'" in capsys.readouterr().err

    def no_dns(*args: object, **kwargs: object) -> object:
        raise socket.gaierror(socket.EAI_NONAME, "Name or service not known")

    monkeypatch.setattr(socket, "getaddrinfo", no_dns)
    for tool in (ls, echo):
        args = ["--timeout", "1"] if tool is ls else ["/x", "--duration", "1"]
        assert tool.main([*args, "--node", "rig-pc.invalid:9000"]) == 2
        err = capsys.readouterr().err  # was a socket.gaierror traceback
        assert "cannot resolve host 'rig-pc.invalid'" in err and len(err.strip().splitlines()) == 1


def test_ls_never_credits_one_node_with_another_nodes_answer(capsys: pytest.CaptureFixture[str]) -> None:
    """Two machines run their nodes on the same port: only the one that answered is "ok" (the answer was
    matched by port alone, so a dead node showed the live one's health)."""
    live = FakeNode(host="127.0.0.2")
    try:
        assert ls.main(["--node", f"127.0.0.1:{live.port}", "--node", f"127.0.0.2:{live.port}", "--timeout", "3"]) == 1
        rows = capsys.readouterr().out.splitlines()[1:]
        assert "no answer" in rows[0] and "fake-1" not in rows[0]
        assert "fake-1" in rows[1] and " ok " in rows[1]  # the garbage and the huge datagram before it were dropped
    finally:
        live.close()


def test_ls_json_reports_the_refusals_a_node_left_unanswered(fake_node: FakeNode,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    """A flood of bad packets shows in ``batteur ls --json`` (the Health counts past the reply budget)."""
    assert ls.main(["--node", f"127.0.0.1:{fake_node.port}", "--timeout", "3", "--json"]) == 0
    row = json.loads(capsys.readouterr().out)[0]
    assert (row["status"], row["decode_unanswered"], row["replies_unanswered"]) == ("ok", 7, 5)


def test_ls_and_echo_reach_an_ipv6_node(capsys: pytest.CaptureFixture[str]) -> None:
    try:
        node = FakeNode(host="::1")
    except OSError:
        pytest.skip("no IPv6 loopback here")
    try:  # the tool listened on IPv4 only: "cannot reach IPv6 ::1 from an IPv4 socket", "no answer"
        assert ls.main(["--node", f"[::1]:{node.port}", "--timeout", "5"]) == 0
        assert "fake-1" in capsys.readouterr().out
    finally:
        node.close()


def test_ls_shows_a_node_it_cannot_reach_instead_of_hiding_it(monkeypatch: pytest.MonkeyPatch,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    import common.discovery

    async def browse(timeout_s: float, interfaces: Sequence[str] | None = None) -> list[NodeInfo]:
        return [NodeInfo(role="sound", node_id="lan-only", host="", port=9000, protocol=1, addresses=("10.9.9.9",))]

    monkeypatch.setattr(common.discovery, "browse_nodes", browse)
    assert ls.main(["--browse", "1", "--timeout", "1", "--json"]) == 1
    out = capsys.readouterr().out  # was "no nodes found": the node the user is looking for, silently dropped
    assert '"node_id": "lan-only"' in out and '"status": "no address"' in out and "10.9.9.9" in out


# --------------------------------------------------------------------------- echo


@pytest.mark.parametrize(("pattern", "says"), [
    ("/batteur/[abc", "'[' without ']'"),  # a node refuses it silently: echo printed nothing, exit 0
    ("/batteur/{impact", "'{' without '}'"),
    ("/" + "a" * 300, "at most 256 characters"),  # was a multi-line pydantic error
])
def test_echo_refuses_a_malformed_pattern_in_one_line(pattern: str, says: str,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    assert echo.main([pattern, "--node", f"127.0.0.1:{free_port()}", "--duration", "1"]) == 2
    err = capsys.readouterr().err
    assert says in err and len(err.strip().splitlines()) == 1


def test_echo_count_must_be_at_least_one(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as refused:  # -1 meant "never stop"
        echo.main(["/x", "--node", "127.0.0.1:9", "--count", "-1"])
    assert refused.value.code == 2 and "--count" in capsys.readouterr().err


def test_echo_says_when_a_node_does_not_answer(capsys: pytest.CaptureFixture[str]) -> None:
    port = free_port()
    assert echo.main(["/batteur/*", "--node", f"127.0.0.1:{port}", "--duration", "1"]) == 1  # was 0, in silence
    assert f"127.0.0.1:{port} did not answer" in capsys.readouterr().err


def test_echo_prints_only_what_matches_and_stops_quietly_when_its_reader_goes(fake_node: FakeNode) -> None:
    proc = batteur("echo", "/batteur/hello", "--node", f"127.0.0.1:{fake_node.port}")
    try:
        assert proc.stdout is not None and proc.stderr is not None
        lines = [proc.stdout.readline() for _ in range(3)]
        assert all(line.startswith("/batteur/hello 'cli' 'seen'") for line in lines), lines  # no /batteur/health
        proc.stdout.close()  # `batteur echo ... | head -3`: head has its lines and exits
        assert proc.wait(timeout=60) == 0  # ran on for ever, logging a BrokenPipeError per message
        err = proc.stderr.read()
        assert "Broken" not in err and "Traceback" not in err, err
    finally:
        proc.kill()
        proc.wait()


def test_echo_ctrl_c_exits_130_without_a_traceback(fake_node: FakeNode) -> None:
    proc = batteur("echo", "/batteur/hello", "--node", f"127.0.0.1:{fake_node.port}")
    try:
        assert proc.stdout is not None
        assert proc.stdout.readline().startswith("/batteur/hello")
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=30)
        assert proc.returncode == 130 and "Traceback" not in err, err  # was 0, as if it had finished
    finally:
        proc.kill()
        proc.wait()


# --------------------------------------------------------------------------- OSCQuery


def test_oscquery_requests_do_not_flood_the_node_log(caplog: pytest.LogCaptureFixture) -> None:
    async def main() -> None:
        server = OscQueryServer("n1", "sound", "127.0.0.1", 9000)
        await server.start()
        try:
            for _ in range(3):  # a client polling the namespace
                await asyncio.to_thread(lambda: urllib.request.urlopen(f"http://127.0.0.1:{server.port}/").read())
        finally:
            await server.stop()

    caplog.set_level(logging.INFO)
    asyncio.run(main())
    noise = [r.getMessage() for r in caplog.records if r.levelno < logging.WARNING and "HTTP" in r.getMessage()]
    assert noise == []  # was two INFO lines per request ("HTTP response sent", "connection closed")


# --------------------------------------------------------------------------- discovery


def test_an_extra_service_port_is_checked_when_given() -> None:
    discovery = Discovery("sound", "n1", 9000)
    with pytest.raises(ValueError, match="out of range"):  # was accepted, then a struct.error inside zeroconf
        asyncio.run(discovery.register_extra("_oscjson._tcp.local.", 99999, {}))


@pytest.fixture
def netns_lab() -> Iterator[NetnsLab]:
    require_netns()
    with NetnsLab() as lab:
        yield lab


def ns_popen(ns: Namespace, *args: str) -> subprocess.Popen[str]:
    env = dict(os.environ, PYTHONPATH=str(REPO), PYTHONUNBUFFERED="1")
    return subprocess.Popen(ns.exec_args(sys.executable, *args), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=env, preexec_fn=child_takes_sigint)


@pytest.mark.netns
def test_discovery_command_line_errors_are_one_line(netns_lab: NetnsLab) -> None:
    ns = netns_lab.namespace("cli")
    run = ["-m", "common.discovery", "run", "--role", "sound", "--node-id", "s1", "--duration", "1"]
    cases = [
        ([*run, "--port", "9000", "--peer", "garbage"], "expected ROLE=HOST:PORT"),  # was a traceback
        ([*run, "--port", "9000", "--extra", "_oscjson._tcp.local.:99999"], "port 1-65535"),  # struct.error
        ([*run, "--port", "9000", "--extra", "garbage"], "expected TYPE:PORT"),  # "invalid literal for int()"
        ([*run, "--port", "0"], "give a port from 1 to 65535"),  # pydantic's four lines in a JSON string
        ([*run, "--port", "9000", "--check-interval", "0"], "--check-interval"),  # was a busy loop
        ([*run, "--port", "9000", "--duration", "-1"], "--duration"),  # meant "until a signal"
        (["-m", "common.discovery", "ls", "--timeout", "nan"], "--timeout"),  # listed nothing, exit 0
        (["-m", "common.discovery", "ls", "--interface", "eth9"], "interface 'eth9'"),  # was a traceback
    ]
    for args, says in cases:
        proc = ns_popen(ns, *args)
        out, err = proc.communicate(timeout=60)
        assert proc.returncode == 2, (args, out, err)
        assert says in out + err and "Traceback" not in err, (args, out, err)


@pytest.mark.netns
def test_discovery_ls_ctrl_c_exits_130_without_a_traceback(netns_lab: NetnsLab) -> None:
    ns = netns_lab.namespace("intr")
    proc = ns_popen(ns, "-m", "common.discovery", "-v", "ls", "--timeout", "60")
    try:
        assert proc.stderr is not None
        for line in proc.stderr:  # -v: zeroconf logs its first query: the browse is under way
            if "Sending to" in line:
                break
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=30)
        assert proc.returncode == 130 and "Traceback" not in err, err  # was a KeyboardInterrupt traceback
    finally:
        proc.kill()
        proc.wait()


BROWSE_WITH_A_BROKEN_RECORD = """
import asyncio, json
import common.discovery as d

class Flaky(d.AsyncServiceInfo):
    async def async_request(self, *args, **kwargs):
        if self.name.startswith("sound-odd"):
            raise ValueError("an odd record")
        return await super().async_request(*args, **kwargs)

d.AsyncServiceInfo = Flaky
print(json.dumps({"found": [n.node_id for n in asyncio.run(d.browse_nodes(3.0))]}))
"""


@pytest.mark.netns
def test_one_odd_service_does_not_lose_the_listing(netns_lab: NetnsLab) -> None:
    ns = netns_lab.namespace("odd")
    for node_id, port in (("good", "9000"), ("odd", "9001")):
        node = ns.python("-m", "common.discovery", "run", "--role", "sound", "--node-id", node_id, "--port", port)
        node.expect(lambda e: e.get("event") == "started", 30.0)
    browse = ns.python("-c", BROWSE_WITH_A_BROKEN_RECORD)
    assert browse.wait(timeout=30) == 0, browse.describe("browse failed")  # the whole listing was a traceback
    assert browse.events() == [{"found": ["good"]}]


def _answering_node(answers: list[tuple[str, list[object]]]) -> tuple[socket.socket, threading.Thread]:
    """A UDP node on 127.0.0.1 that answers the first datagram it gets with ``answers`` (address, args)."""
    from common.messages import encode_raw

    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(30.0)

    def serve() -> None:
        _, source = sock.recvfrom(65536)
        for address, args in answers:
            sock.sendto(encode_raw(address, args), source)  # type: ignore[arg-type]

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    return sock, thread


def test_send_replies_prints_the_answers_and_fails_on_a_refusal(capsys: pytest.CaptureFixture[str]) -> None:
    """``--replies``: a control a node refuses (its error comes back to the sender) no longer passes as sent."""
    node, thread = _answering_node([("/batteur/interaction/error", ["/batteur/interaction/route/remove",
                                                                    "no route to 'nope'"])])
    with node:
        to = f"127.0.0.1:{node.getsockname()[1]}"
        assert send.main(["/batteur/interaction/route/remove", "nope", "--to", to, "--replies", "2"]) == 1
        thread.join(5.0)
    assert f"{to} /batteur/interaction/error /batteur/interaction/route/remove no route to 'nope'" in \
        capsys.readouterr().out
    node, thread = _answering_node([("/batteur/interaction/map/info", ["sound", "*", "", ""]),
                                    ("/batteur/interaction/list/end", ["map", 1])])
    with node:
        to = f"127.0.0.1:{node.getsockname()[1]}"
        assert send.main(["/batteur/interaction/map/list", "--to", to, "--replies", "0.5"]) == 0
        thread.join(5.0)
    assert f"{to} /batteur/interaction/list/end map 1" in capsys.readouterr().out


def test_send_replies_says_when_nothing_listens(capsys: pytest.CaptureFixture[str]) -> None:
    port = free_port()  # a port nobody listens on
    assert send.main(["/batteur/interaction/map/list", "--to", f"127.0.0.1:{port}"]) == 0  # UDP: sent is all
    assert send.main(["/batteur/interaction/map/list", "--to", f"127.0.0.1:{port}", "--replies", "1"]) == 1
    assert f"nothing listens at 127.0.0.1:{port}" in capsys.readouterr().err
