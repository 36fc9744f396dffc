"""``batteur send`` with a rig time written ``+SECONDS``: that long after the destination node's rig time, which
send asks the node for first (the Health it answers a Hello, as ``batteur ls``). A user could not learn the rig
time in time: Health's time + 1 s was already past when ``send`` ran."""

from __future__ import annotations

import select
import socket
import threading
import time
from collections.abc import Iterator
from time import monotonic, sleep
from typing import Any

import pytest

from batteur.tools import send
from common.messages import Health, RawMessage, encode, parse_packet
from common.messages.physics import PhysicsRejected
from tests.ports import free_port

pytestmark = pytest.mark.timeout(60)

RIG_TIME_S = 1000.25
"""The stand-in node's rig time (exact in the wire's whole seconds and float32 fraction)."""


class StandIn:
    """A node on 127.0.0.1 that answers a Hello with a Health at :data:`RIG_TIME_S` (unless ``silent``) and keeps
    every other message it receives."""

    def __init__(self, silent: bool = False, answer_delay_s: float = 0.0, refusal: str = "") -> None:
        self.silent = silent
        self.answer_delay_s = answer_delay_s
        """How long its Health, stamped :data:`RIG_TIME_S`, takes to leave: a slow round trip (a loaded machine)."""
        self.refusal = refusal
        """A reason to refuse every other message with (physics' /batteur/physics/rejected), with ``{at}`` the rig
        time it was for and ``{arrived}`` 180 ms before it; "" refuses none."""
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", free_port()))
        self.address = f"127.0.0.1:{self.sock.getsockname()[1]}"
        self.hellos = 0
        self.received: list[RawMessage] = []
        self.got = threading.Event()
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self.serve, daemon=True)

    def serve(self) -> None:
        health = Health(node_id="physics-1", role="physics", protocol=1, time=RIG_TIME_S, rate_hz=1000.0,
                        target_rate_hz=1000.0, overruns=0, messages_in=0, messages_out=0, dropped=0,
                        dropped_malformed=0, dropped_unknown=0, dropped_type=0, dropped_range=0, dropped_other=0,
                        late=0, peers=0)
        while not self.stop.is_set():
            ready, _, _ = select.select([self.sock], [], [], 0.05)
            if not ready:
                continue
            data, source = self.sock.recvfrom(65536)
            for raw in parse_packet(data):
                if raw.address == "/batteur/hello":
                    self.hellos += 1
                    if not self.silent:
                        time.sleep(self.answer_delay_s)
                        self.sock.sendto(encode(health), source)
                else:
                    self.received.append(raw)
                    if self.refusal:
                        at = float(raw.args[0]) + float(raw.args[1])  # type: ignore[arg-type]
                        reason = self.refusal.format(at=at, arrived=at - 0.18)  # it came 180 ms before its time
                        self.sock.sendto(encode(PhysicsRejected(address=raw.address, reason=reason)), source)
                    self.got.set()

    def close(self) -> None:
        self.stop.set()
        self.thread.join(5)
        self.sock.close()


def stand_in(silent: bool, answer_delay_s: float = 0.0, refusal: str = "") -> Iterator[StandIn]:
    node = StandIn(silent, answer_delay_s, refusal)
    node.thread.start()
    yield node
    node.close()


@pytest.fixture
def node() -> Iterator[StandIn]:
    yield from stand_in(silent=False)


@pytest.fixture
def silent_node() -> Iterator[StandIn]:
    yield from stand_in(silent=True)


@pytest.mark.parametrize(("time", "expected"), [("+2", RIG_TIME_S + 2), ("+0.5", RIG_TIME_S + 0.5)])
def test_a_relative_time_is_after_the_nodes_rig_time(node: StandIn, time: str, expected: float) -> None:
    began = monotonic()
    assert send.main(["/batteur/score/transport", "play", time, "3", "--to", node.address]) == 0
    took = monotonic() - began
    assert node.got.wait(5)
    [play] = node.received
    assert play.address == "/batteur/score/transport"
    whole, fraction = play.args[1], play.args[2]
    assert isinstance(whole, int) and isinstance(fraction, float)
    assert (play.args[0], play.args[3]) == ("play", 3.0)
    # the node's rig time when send sent it: its Health's, plus the time the Health took to come and has waited
    # since, all within the time send ran
    assert expected <= whole + fraction <= expected + took + 1e-3
    assert node.hellos == 1


def note_time(node: StandIn, offset: str = "+0.5") -> float:
    """The rig time of the note ``batteur send /batteur/score/note OFFSET 38 100 10`` sends ``node``."""
    assert send.main(["/batteur/score/note", offset, "38", "100", "10", "--to", node.address]) == 0
    assert node.got.wait(5)
    [note] = node.received
    whole, fraction = note.args[0], note.args[1]
    assert isinstance(whole, int) and isinstance(fraction, float)
    return whole + fraction


def test_a_slow_round_trip_does_not_make_the_note_late() -> None:
    """The node's Health leaves 0.4 s after its rig time was read (a loaded machine): the note is made from the
    rig time when it is sent, half the round trip (at least 0.2 s) later than the Health said; it was the Health's
    time + 0.5, a note already late when it came."""
    for node in stand_in(silent=False, answer_delay_s=0.4):
        assert note_time(node) >= RIG_TIME_S + 0.5 + 0.4 / 2


def test_time_spent_after_the_health_came_is_counted(monkeypatch: pytest.MonkeyPatch) -> None:
    """Send held up for 0.3 s after the node's Health came (a loaded machine, more nodes to ask): the rig time is
    resolved right before sending, those 0.3 s later."""
    asked = send.rig_times

    def slow(*args: Any, **kwargs: Any) -> Any:
        answers = asked(*args, **kwargs)
        sleep(0.3)
        return answers

    monkeypatch.setattr(send, "rig_times", slow)
    for node in stand_in(silent=False):
        assert note_time(node) >= RIG_TIME_S + 0.5 + 0.3


LATE = "live note snare at {at:.3f} s arrived at {arrived:.3f} s: less than 300 ms to prepare it; not played"
"""Physics' refusal of a live note too late to prepare (services/physics/score_player.py)."""


def test_a_note_refused_as_late_says_how_late_and_a_larger_offset(capsys: pytest.CaptureFixture[str]) -> None:
    """Physics' refusal of a note too late to prepare (it came 180 ms before its time, where it needs 300 ms) is
    followed by how late it was and a larger +SECONDS: the next half second above what it lacked."""
    for node in stand_in(silent=False, refusal=LATE):
        code = send.main(["/batteur/score/note", "+0.5", "38", "100", "10", "--to", node.address, "--replies", "2"])
        at = note_time_of(node)
    out, err = capsys.readouterr()
    assert code == 1 and "/batteur/physics/rejected /batteur/score/note live note snare at" in out
    hint = [line for line in err.splitlines() if "came too late" in line]
    assert hint == [f"batteur send: +0.5 s was rig time {at:.3f} s and came too late: it arrived 180 ms before its "
                    "time, 120 ms short of the 300 ms the node needs to prepare it; a larger offset leaves more: try "
                    "+1"], err


def note_time_of(node: StandIn) -> float:
    """The rig time of the one note ``node`` received."""
    assert node.got.wait(5)
    [note] = node.received
    return float(note.args[0]) + float(note.args[1])  # type: ignore[arg-type]


def test_another_refusal_suggests_no_offset(capsys: pytest.CaptureFixture[str]) -> None:
    """A refusal that is not about time (a pitch of no drum) says nothing of offsets: a larger one would not help."""
    for node in stand_in(silent=False, refusal="live note: pitch 20 has no drum event type; not played"):
        code = send.main(["/batteur/score/note", "+0.5", "20", "100", "10", "--to", node.address, "--replies", "2"])
    out, err = capsys.readouterr()
    assert code == 1 and "pitch 20 has no drum event type" in out and "offset" not in err


@pytest.mark.parametrize(("reason", "said"), [
    ("strike at 1000.750 s is in the past (now 1001.000 s)", "it arrived 250 ms after its time; a larger offset "
     "leaves more: try +1"),
    ("live note snare at 1000.750 s arrived at 1000.700 s: less than 300 ms to prepare it; not played",
     "it arrived 50 ms before its time, 250 ms short of the 300 ms the node needs to prepare it; a larger offset "
     "leaves more: try +1"),
    ("live note snare at 1001.750 s arrived at 1000.100 s: less than 2500 ms to prepare it; not played",
     "it arrived 1650 ms before its time, 850 ms short of the 2500 ms the node needs to prepare it; a larger offset "
     "leaves more: try +1.5"),
    # late for another cause than its lead (the planner still loading): a larger offset would not help
    ("live note snare at 1000.750 s arrived at 1000.100 s: the planning process is still loading the planner (4.0 s "
     "so far); not played", None),
])
def test_how_late_is_read_from_the_node_s_reason(reason: str, said: str | None) -> None:
    hint = send.late_hint(reason, 0.5, 1000.75)
    assert hint == (None if said is None else f"batteur send: +0.5 s was rig time 1000.750 s and came too late: {said}")



def test_a_late_refusal_with_lead_enough_advises_no_offset() -> None:
    """A note refused as late though it came with the lead the node needs (450 ms of 300 ms): refused for another
    timing reason, quoted; no "0 ms short ... try +1"."""
    reason = "live note snare at 1000.750 s arrived at 1000.300 s: less than 300 ms to prepare it; not played"
    hint = send.late_hint(reason, 0.5, 1000.75)
    assert hint == ("batteur send: +0.5 s was rig time 1000.750 s and arrived 450 ms before its time, at least the "
                    "300 ms the node needs to prepare it: the node refused it for another timing reason "
                    f"({reason!r}); a larger offset may not help")
    assert "try +" not in hint and "short" not in hint


def test_an_absolute_time_asks_the_node_nothing(node: StandIn) -> None:
    assert send.main(["/batteur/score/transport", "play", "12.25", "0", "--to", node.address]) == 0
    assert node.got.wait(5)
    assert [r.args for r in node.received] == [["play", 12, 0.25, 0.0]] and node.hellos == 0


def test_a_node_that_does_not_say_its_rig_time_is_one_line_and_exit_1(silent_node: StandIn,
                                                                      capsys: pytest.CaptureFixture[str]) -> None:
    code = send.main(["/batteur/score/transport", "play", "+2", "0", "--to", silent_node.address, "--timeout",
                      "0.3"])
    err = capsys.readouterr().err
    assert code == 1
    # the flag that gives a loaded machine longer is named (a walkthrough's node answered within 15 s, not 2)
    assert err.splitlines() == [f"batteur send: error: no rig time from {silent_node.address} within --timeout 0.3 s "
                                "(its Health did not come: is a Batteur node running there?); +SECONDS needs it, not "
                                "sent (a loaded machine may answer later: raise --timeout, e.g. --timeout 10)"]
    assert silent_node.hellos == 1 and silent_node.received == []  # asked, and nothing sent


@pytest.mark.parametrize("time", ["+", "+x", "+-1", "++1", "+inf", "+nan"])
def test_a_bad_relative_time_is_refused_before_any_node_is_asked(silent_node: StandIn, time: str,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    code = send.main(["/batteur/score/transport", "play", time, "0", "--to", silent_node.address])
    err = capsys.readouterr().err
    assert code == 2
    assert f"TIME: +SECONDS must be a finite number of seconds, 0 or more, got {time!r}" in err
    assert silent_node.hellos == 0


def test_the_help_says_how_to_write_a_relative_time(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        send.main(["--help"])
    assert "+SECONDS is that long after the node's rig time" in " ".join(capsys.readouterr().out.split())


class AnswersFromAnother(StandIn):
    """A node on 127.0.0.1 whose answers leave from another of its addresses (127.0.0.2: loopback too)."""

    def __init__(self) -> None:
        super().__init__()
        self.alt = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.alt.bind(("127.0.0.2", 0))
        real, alt = self.sock, self.alt

        class Sock:  # receives on 127.0.0.1, sends from 127.0.0.2
            def __getattr__(self, name: str) -> Any:
                return getattr(real, name)

            def sendto(self, data: bytes, address: Any) -> int:
                return alt.sendto(data, address)

            def fileno(self) -> int:
                return real.fileno()

        self.sock = Sock()  # type: ignore[assignment]

    def close(self) -> None:
        super().close()
        self.alt.close()


def test_a_health_from_another_address_is_said(capsys: pytest.CaptureFixture[str]) -> None:
    """The Health came, from 127.0.0.2: the error says so, not "is a Batteur node running there?"."""
    node = AnswersFromAnother()
    stray = f"127.0.0.2:{node.alt.getsockname()[1]}"
    node.thread.start()
    try:
        code = send.main(["/batteur/score/note", "+0.5", "38", "100", "10", "--to", node.address, "--timeout", "1"])
    finally:
        node.close()
    err = capsys.readouterr().err
    assert code == 1 and node.hellos == 1 and node.received == []
    assert (f"no rig time from {node.address} within --timeout 1 s (a Health came from {stray} (node physics-1), "
            f"not from {node.address}: a node answering from another of its addresses is not taken" in err), err
    assert "is a Batteur node running there" not in err
