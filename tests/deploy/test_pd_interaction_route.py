"""The Pd control panel's INTERACTION section routes a rig's impacts to the Pd sound client (and removes the route);
the Pd sound client says once that the panel's SOUND messages are not for it.

A real ``batteur interaction`` node runs on loopback (discovery off, no configuration file); the panel is driven
through its receive names (``pd -send``); a UDP socket stands at the client's port."""

from __future__ import annotations

import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from common.messages import Impact, decode, encode, encode_raw
from common.messages.interaction import ListEnd, MapInfo, MapList
from common.messages.sound import SoundLatency, SoundTension
from tests.deploy.pdrun import PD_DIR, THREE_STRIKES, PdProcess, require_pd, three_strikes
from tests.deploy.test_pd_refusals import refusals
from tests.ports import free_port
from tests.waiting import until

pytestmark = pytest.mark.timeout(120)
ROOT = Path(__file__).resolve().parents[2]


@contextmanager
def interaction_node() -> Iterator[int]:
    """A ``batteur interaction`` process on a loopback port (returned), with no peers and no configuration file,
    listening when this yields; stopped (and checked to exit cleanly) on exit."""
    port = free_port()
    node = subprocess.Popen(
        [sys.executable, "-m", "batteur", "interaction", "--port", str(port), "--no-discovery",
         "--clock-master", "self", "--interaction-config", "none", "--no-oscquery"],
        cwd=str(ROOT), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True)
    log: list[str] = []
    reader = threading.Thread(target=lambda: log.extend(node.stderr or ()), daemon=True)
    reader.start()
    try:
        listening = until(lambda: node.poll() is not None or any("listening on" in line and " node " in line
                                                                  for line in log), timeout_s=60)
        assert listening and node.poll() is None, "".join(log)
        yield port
    finally:
        node.terminate()
        try:
            node.wait(timeout=10)
        except subprocess.TimeoutExpired:
            node.kill()
        reader.join(timeout=10)
    assert node.returncode == 0, "".join(log)


def routes(iport: int) -> dict[str, str]:
    """to: instruments of each route the interaction node at ``iport`` has (its answer to map/list)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        s.settimeout(10)
        s.sendto(encode(MapList()), ("127.0.0.1", iport))
        found: dict[str, str] = {}
        while True:
            for message in decode(s.recvfrom(65536)[0]).messages:
                if isinstance(message, MapInfo) and message.field == "":
                    found[message.to] = message.instruments
                if isinstance(message, ListEnd) and message.what == "map":
                    return found


def test_the_panel_routes_impacts_to_the_pd_client_port_and_removes_the_route() -> None:
    """The panel's route button (client port chosen in its box) makes interaction send every impact to that port:
    three strikes fed to interaction as physics contacts arrive there. A second panel's remove button takes the
    route away again."""
    require_pd()
    with interaction_node() as iport, socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as client:
        client.bind(("127.0.0.1", free_port()))
        client.settimeout(15)
        target = f"127.0.0.1:{client.getsockname()[1]}"
        assert target not in routes(iport)
        pd = PdProcess(PD_DIR / "control.pd", sends=[f"bp-port-interaction {iport}",
                                                     f"bp-client-port {client.getsockname()[1]}",
                                                     "bp-client-route bang"])
        try:
            assert until(lambda: target in routes(iport), timeout_s=20), "\n".join(pd.lines)
        finally:
            pd.stop()
        assert routes(iport)[target] == "*"  # every instrument
        assert pd.errors() == [], "\n".join(pd.lines)
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as physics:
            start = time.monotonic()  # contacts go out at their own pace, one physics step apart, as physics sends
            for contact in three_strikes():
                wait = start + contact.time - time.monotonic()
                if wait > 0:
                    time.sleep(wait)
                physics.sendto(encode(contact), ("127.0.0.1", iport))
        heard: dict[int, Impact] = {}  # by sequence number: interaction sends each impact several times
        while len(heard) < len(THREE_STRIKES):
            for message in decode(client.recvfrom(65536)[0]).messages:
                if isinstance(message, Impact):
                    heard[message.seq] = message
        played = sorted(heard.values(), key=lambda m: m.time)
        assert [m.instrument for m in played] == [name for name, _ in THREE_STRIKES]
        assert [m.time for m in played] == pytest.approx([at for _, at in THREE_STRIKES], abs=0.0015)

        pd = PdProcess(PD_DIR / "control.pd", sends=[f"bp-port-interaction {iport}",
                                                     f"bp-client-port {client.getsockname()[1]}",
                                                     "bp-client-remove bang"])
        try:
            assert until(lambda: target not in routes(iport), timeout_s=20), "\n".join(pd.lines)
        finally:
            pd.stop()
        assert pd.errors() == [], "\n".join(pd.lines)


def test_the_panel_routes_to_the_host_typed_and_shows_interactions_refusal() -> None:
    """The client host box goes into the route (host:port); removing a route interaction does not have is refused,
    and the refusal comes back to the panel, printed as the other services' are."""
    require_pd()
    with interaction_node() as iport:
        pd = PdProcess(PD_DIR / "control.pd", sends=[f"bp-port-interaction {iport}", "bp-client-port 9203",
                                                     "bp-client-host symbol 127.0.0.2", "bp-client-route bang",
                                                     "bp-client-port 9204", "bp-client-remove bang"])
        try:
            assert until(lambda: bool(refusals(pd)), timeout_s=20), "\n".join(pd.lines)
            assert routes(iport).get("127.0.0.2:9203") == "*"
        finally:
            pd.stop()
    assert refusals(pd) == [("/batteur/interaction/route/remove", "no route to '127.0.0.2:9204'")]


def test_the_sound_client_says_once_that_sound_messages_are_for_the_pyo_service() -> None:
    """The panel's SOUND controls sent to the Pd client's port (both default to 9103) get one line saying the
    client ignores them, not one per message, and are not counted as bad input."""
    port = free_port()
    pd = PdProcess(PD_DIR / "sound-client.pd", sends=[f"sc-port {port}"])
    try:
        pd.wait_for(lambda lines: any(f"listen {port}" in line for line in lines))
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.sendto(encode(SoundTension(instrument="kick", value=800)), ("127.0.0.1", port))
            s.sendto(encode(SoundLatency(value=0.08)), ("127.0.0.1", port))
            s.sendto(encode_raw("/pd/bogus", []), ("127.0.0.1", port))  # Pd handles datagrams in order: a marker
            pd.wait_for(lambda lines: bool(pd.printed("batteur-bad")))
    finally:
        pd.stop()
    said = [" ".join(atoms) for atoms in pd.printed("batteur-not-sound")]
    assert len(said) == 1, "\n".join(pd.lines)
    assert said[0].startswith("/batteur/sound/tension is for the pyo sound service")
    assert "bp-port-sound" in said[0]
    assert pd.printed("batteur-bad") == [["1", "/pd/bogus", "is", "not", "an", "address", "of", "this", "client"]]
    assert pd.errors() == [], "\n".join(pd.lines)
