"""Run Pure Data headless (``pd -nogui -nosound``) for tests and read what its [print] objects say."""

from __future__ import annotations

import os
import queue
import shutil
import socket
import subprocess
import threading
import time
from collections.abc import AsyncIterator, Callable, Iterator, Sequence
from contextlib import asynccontextmanager, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import pytest

from common.config import load_settings
from common.core import Outgoing
from common.kit import load_kit
from common.messages import OscMessage, decode
from common.messages.events import Contact
from common.runtime import Node
from services.interaction.synthetic import StreamBuilder, strike
from tests.ports import free_ports

PD_DIR = Path(__file__).resolve().parents[2] / "pd"


def pd_binary() -> str | None:
    return shutil.which("pd") or shutil.which("puredata")


def require_pd() -> str:
    binary = pd_binary()
    if binary is None:
        pytest.skip("Pure Data is not installed (Debian: apt-get install puredata-core)")
    return binary


class PdProcess:
    """``pd -nogui -nosound -stderr PATCH`` with ``-send`` messages; stderr lines collected."""

    def __init__(self, patch: Path, sends: Sequence[str] = (), extra: Sequence[str] = (),
                 prefix: Sequence[str] = ()) -> None:
        binary = require_pd()
        args = [*prefix, binary, "-nogui", "-nosound", "-stderr", "-noprefs", *extra]
        for message in sends:
            args += ["-send", message]
        args.append(str(patch))
        self.popen = subprocess.Popen(args, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                      stderr=subprocess.STDOUT, text=True, cwd=str(patch.parent),
                                      start_new_session=True)
        self.lines: list[str] = []
        self._queue: queue.Queue[str | None] = queue.Queue()
        self._reader = threading.Thread(target=self._pump, daemon=True)
        self._reader.start()

    def _pump(self) -> None:
        assert self.popen.stdout is not None
        for line in self.popen.stdout:
            self._queue.put(line.rstrip("\n"))
        self._queue.put(None)

    def _drain(self, timeout: float) -> None:
        try:
            line = self._queue.get(timeout=timeout)
        except queue.Empty:
            return
        if line is not None:
            self.lines.append(line)

    def wait_for(self, predicate: Callable[[list[str]], bool], timeout: float = 10.0) -> list[str]:
        deadline = time.monotonic() + timeout
        while not predicate(self.lines):
            if time.monotonic() > deadline:
                raise AssertionError(f"Pd did not print what was expected within {timeout} s:\n" +
                                     "\n".join(self.lines[-50:]))
            if self.popen.poll() is not None and self._queue.empty():
                raise AssertionError("Pd exited:\n" + "\n".join(self.lines[-50:]))
            self._drain(0.05)
        return self.lines

    def printed(self, name: str) -> list[list[str]]:
        """The atoms printed by ``[print NAME]`` so far (Pd writes ``NAME: atoms``)."""
        while not self._queue.empty():
            self._drain(0)
        out = []
        for line in self.lines:
            if line.startswith(name + ":"):
                atoms = line[len(name) + 1:].split()
                if atoms and atoms[0] in ("list", "symbol"):
                    atoms = atoms[1:]
                out.append(atoms)
        return out

    def errors(self) -> list[str]:
        """Lines that look like Pd errors (object creation failures, wires between outlets and inlets that do not
        exist, bad messages)."""
        bad = ("couldn't create", "error", "no method", "bad arguments", "stack overflow", "connection failed")
        return [line for line in self.lines if any(b in line for b in bad)]

    def stop(self) -> None:
        if self.popen.poll() is None:
            self.popen.terminate()
            try:
                self.popen.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.popen.kill()
                self.popen.wait(timeout=5)
        self._reader.join(timeout=2)


THREE_STRIKES = (("snare", 0.2), ("floortom", 0.5), ("crash", 0.8))
"""(instrument, rig time s) of the strikes :func:`three_strikes` makes."""


def three_strikes() -> list[Contact]:
    """Physics' contact stream of a snare, floor tom and crash strike at 4 m/s (:data:`THREE_STRIKES`), in step
    order: what a Pd sound client must play once each."""
    kit = load_kit("default")
    contacts: list[Contact] = []
    for instrument, at in THREE_STRIKES:
        builder = StreamBuilder(kit, instrument)
        strike(builder, at, velocity=4.0)
        contacts += builder.contacts
    return sorted(contacts, key=lambda c: c.step)


class Recorder:
    """Wraps a real core: records what it handled, handles it, never steps (rate 0 keeps the test light)."""

    ROLE: ClassVar[str] = "wrapped"

    def __init__(self, core: Any) -> None:
        self.core = core
        self.rate_hz = 0.0
        self.handled: list[OscMessage] = []

    def handle(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        self.handled.append(message)
        out: list[Outgoing] = self.core.handle(message, now, source)
        return out

    def step(self, now: float) -> list[Outgoing]:
        return []

    def of(self, kind: type[OscMessage]) -> list[Any]:
        return [m for m in self.handled if isinstance(m, kind)]


@dataclass
class PanelTargets:
    """Real physics and sound cores (recorded) as nodes on loopback, for the control panel to drive."""

    physics: Recorder
    sound: Recorder
    physics_port: int
    sound_port: int
    nodes: list[Node]


@asynccontextmanager
async def physics_and_sound_nodes() -> AsyncIterator[PanelTargets]:
    """Start a physics node and a sound node (no discovery, their own clocks, no pyo) around recorded real cores;
    stopped on exit."""
    from services.physics.core import PhysicsCore
    from services.sound.core import SoundCore, SoundSettings

    physics = Recorder(PhysicsCore())
    sound = Recorder(SoundCore(SoundSettings(use_pyo=False)))
    nodes = []
    try:
        for role, core in (("physics", physics), ("sound", sound)):
            node = Node(core, load_settings({"role": role, "discovery": False,  # type: ignore[arg-type]
                                             "clock_master": "self", "oscquery": False}))
            nodes.append(node)
            await node.start()
        pport, sport = (n.endpoint.port for n in nodes if n.endpoint is not None)
        yield PanelTargets(physics, sound, pport, sport, nodes)
    finally:
        for node in nodes:
            await node.stop()


def own_network() -> list[str]:
    """A command prefix running Pd in a network namespace of its own (root and unshare), so a client that
    listens on 9103 does not take this machine's port from a running rig; none without root."""
    unshare = shutil.which("unshare")
    if os.geteuid() != 0 or unshare is None:
        return []
    return [unshare, "--net", "sh", "-c", 'ip link set lo up 2>/dev/null; exec "$@"', "sh"]


# ---------------------------------------------------------------- stand-in services for a Pd patch


class Service:
    """A stand-in service: a UDP socket on a loopback port from tests/ports.py, decoding what it receives."""

    def __init__(self, sock: socket.socket) -> None:
        self.sock = sock
        self.port: int = sock.getsockname()[1]
        self.received: list[OscMessage] = []

    def until(self, done: Callable[[list[OscMessage]], bool], pd: PdProcess) -> list[OscMessage]:
        """Receive until ``done(messages)`` holds; AssertionError (with Pd's output) when nothing more comes."""
        while not done(self.received):
            try:
                data = self.sock.recv(65536)
            except TimeoutError:
                raise AssertionError(f"port {self.port} got only {self.received}:\n" + "\n".join(pd.lines)) from None
            self.received += decode(data).messages
        return self.received


@contextmanager
def services(count: int) -> Iterator[list[Service]]:
    socks = []
    try:
        for port in free_ports(count):
            sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            socks.append(sock)
            sock.bind(("127.0.0.1", port))
            sock.settimeout(15)
        yield [Service(sock) for sock in socks]
    finally:
        for sock in socks:
            sock.close()


def of(kind: type[OscMessage]) -> Callable[[list[OscMessage]], bool]:
    return lambda messages: any(isinstance(m, kind) for m in messages)
