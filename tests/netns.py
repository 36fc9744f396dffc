"""Network namespaces for tests: private loopbacks, veth links and bridges that never touch the host.

Everything here is created inside namespaces the test owns: a veth pair is created directly
with one end in each namespace, a bridge lives in its own "switch" namespace, test addresses
(10.x) exist only inside the namespaces. Cleanup kills the processes started here, then deletes
the namespaces (which destroys their links), even when the test fails.

Usage (the ``netns_lab`` fixture: import it in tests/conftest.py, or define a three-line
fixture around :class:`NetnsLab` in the test module, as tests/test_discovery.py does)::

    def test_something(netns_lab):
        ns = netns_lab.namespace("disc")            # lo up, multicast on
        proc = ns.python("-m", "common.discovery", "run", ...)
        event = proc.expect(lambda e: e["event"] == "started", timeout=10)

    with NetnsLab() as lab:                          # outside pytest
        a, b = lab.namespace("a"), lab.namespace("b")
        addr_a, addr_b = lab.veth(a, b)              # 10.x.y.1/24 <-> 10.x.y.2/24

Tests skip (``pytest.skip``) when not root or when ``ip netns`` does not work here.
"""

from __future__ import annotations

import itertools
import json
import os
import queue
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from functools import lru_cache
from pathlib import Path
from typing import Any

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
PREFIX = "btlab"
"""Every namespace made here is named ``btlab-<pid>-<n>-<tag>`` (stale ones are removed)."""

_counter = itertools.count(1)
_subnets = itertools.count(1)


def _ip(*args: str, timeout: float = 10.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["ip", *args], capture_output=True, text=True, timeout=timeout, check=False)


def _check(result: subprocess.CompletedProcess[str]) -> subprocess.CompletedProcess[str]:
    if result.returncode != 0:
        raise RuntimeError(f"{' '.join(map(str, result.args))} failed ({result.returncode}): {result.stderr.strip()}")
    return result


@lru_cache(maxsize=1)
def netns_unavailable_reason() -> str | None:
    """Why network namespaces cannot be used here, or None when they can."""
    if sys.platform != "linux":
        return "network namespaces need Linux"
    if os.geteuid() != 0:
        return "network namespaces need root"
    if shutil.which("ip") is None:
        return "the 'ip' command (iproute2) is not installed"
    name = f"{PREFIX}-{os.getpid()}-probe"
    added = _ip("netns", "add", name)
    if added.returncode != 0:
        return f"'ip netns add' does not work here: {added.stderr.strip()}"
    _ip("netns", "del", name)
    return None


def require_netns() -> None:
    """Skip the calling test when network namespaces are unavailable."""
    reason = netns_unavailable_reason()
    if reason is not None:
        pytest.skip(reason)


def list_namespaces() -> set[str]:
    """Names of every network namespace ``ip netns`` knows."""
    return {line.split()[0] for line in _ip("netns", "list").stdout.splitlines() if line.split()}


def remove_stale_namespaces() -> list[str]:
    """Delete namespaces left by test processes that no longer exist; returns their names."""
    removed: list[str] = []
    for name in sorted(list_namespaces()):
        parts = name.split("-")
        if len(parts) < 3 or parts[0] != PREFIX or not parts[1].isdigit():
            continue
        pid = int(parts[1])
        if pid == os.getpid() or Path(f"/proc/{pid}").exists():
            continue
        _kill_inside(name)
        if _ip("netns", "del", name).returncode == 0:
            removed.append(name)
    return removed


def _kill_inside(name: str) -> None:
    """SIGKILL every process still inside namespace ``name`` (only ever one this module made)."""
    for token in _ip("netns", "pids", name).stdout.split():
        if token.isdigit():
            try:
                os.kill(int(token), signal.SIGKILL)
            except ProcessLookupError:
                pass


class NsProcess:
    """A process running inside a namespace, with its stdout read line by line in the background.

    ``lines`` holds every stdout line so far; :meth:`expect` waits for a JSON line matching a
    predicate. stderr is kept in ``errors`` for failure messages.
    """

    def __init__(self, args: Sequence[str], env: dict[str, str] | None = None) -> None:
        self.args = list(args)
        self.popen = subprocess.Popen(
            self.args,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=env,
            start_new_session=True,
        )
        self.lines: list[str] = []
        self.errors: list[str] = []
        self._queue: queue.Queue[str | None] = queue.Queue()
        self._cursor = 0
        self._eof = False
        assert self.popen.stdout is not None and self.popen.stderr is not None
        self._readers = [
            threading.Thread(target=self._pump, args=(self.popen.stdout, self._queue), daemon=True),
            threading.Thread(target=self._collect, args=(self.popen.stderr,), daemon=True),
        ]
        for reader in self._readers:
            reader.start()

    @staticmethod
    def _pump(stream: Any, out: queue.Queue[str | None]) -> None:
        for line in stream:
            out.put(line.rstrip("\n"))
        out.put(None)

    def _collect(self, stream: Any) -> None:
        for line in stream:
            self.errors.append(line.rstrip("\n"))

    @property
    def pid(self) -> int:
        return self.popen.pid

    def _drain(self, timeout: float) -> bool:
        """Move one line (waiting up to ``timeout`` s) into ``lines``; False on timeout or EOF."""
        if self._eof:
            return False
        try:
            line = self._queue.get(timeout=max(0.0, timeout))
        except queue.Empty:
            return False
        if line is None:
            self._eof = True
            return False
        self.lines.append(line)
        return True

    def events(self) -> list[dict[str, Any]]:
        """Every JSON object printed so far (non-JSON lines are skipped)."""
        while self._drain(0):
            pass
        found: list[dict[str, Any]] = []
        for line in self.lines:
            try:
                value = json.loads(line)
            except json.JSONDecodeError:
                continue
            if isinstance(value, dict):
                found.append(value)
        return found

    def expect(self, predicate: Callable[[dict[str, Any]], bool], timeout: float = 10.0) -> dict[str, Any]:
        """Wait for the next JSON line (after those already matched) that satisfies ``predicate``.

        Raises
        ------
        AssertionError
            On timeout or process exit, with the output seen so far.
        """
        deadline = time.monotonic() + timeout
        while True:
            while self._cursor < len(self.lines):
                line = self.lines[self._cursor]
                self._cursor += 1
                try:
                    value = json.loads(line)
                except json.JSONDecodeError:
                    continue
                if isinstance(value, dict) and predicate(value):
                    return value
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise AssertionError(self.describe(f"no matching line within {timeout:g} s"))
            if not self._drain(min(remaining, 0.5)) and self._eof:
                self.popen.wait(timeout=5.0)
                raise AssertionError(self.describe("the process ended without a matching line"))

    def describe(self, what: str) -> str:
        return (
            f"{what}: {' '.join(self.args)} (exit {self.popen.poll()})\n"
            "stdout:\n  " + "\n  ".join(self.lines[-40:]) + "\nstderr:\n  " + "\n  ".join(self.errors[-40:])
        )

    def signal(self, sig: int) -> None:
        if self.popen.poll() is None:
            self.popen.send_signal(sig)

    def wait(self, timeout: float = 10.0) -> int:
        return self.popen.wait(timeout=timeout)

    def stop(self, timeout: float = 5.0) -> int:
        """SIGTERM, then SIGKILL after ``timeout`` s; returns the exit code."""
        if self.popen.poll() is None:
            self.popen.send_signal(signal.SIGTERM)
            try:
                self.popen.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                self.popen.kill()
                self.popen.wait(timeout=timeout)
        for reader in self._readers:
            reader.join(timeout=1.0)
        return self.popen.returncode

    def kill(self) -> None:
        """SIGKILL (a crash: no cleanup, no goodbye)."""
        if self.popen.poll() is None:
            self.popen.kill()
            self.popen.wait(timeout=5.0)


class Namespace:
    """One network namespace: ``lo`` is up with multicast on; run commands and processes in it."""

    def __init__(self, lab: NetnsLab, name: str) -> None:
        self.lab = lab
        self.name = name
        self.addresses: list[str] = []  # CIDRs assigned through the lab

    def exec_args(self, *args: str) -> list[str]:
        return ["ip", "netns", "exec", self.name, *args]

    def run(self, *args: str, check: bool = True, timeout: float = 10.0) -> subprocess.CompletedProcess[str]:
        """Run a command inside the namespace and wait for it."""
        result = subprocess.run(self.exec_args(*args), capture_output=True, text=True, timeout=timeout, check=False)
        return _check(result) if check else result

    def ip(self, *args: str) -> subprocess.CompletedProcess[str]:
        """``ip -n NAME ...`` (checked)."""
        return _check(_ip("-n", self.name, *args))

    def popen(self, *args: str, env: dict[str, str] | None = None) -> NsProcess:
        """Start a process inside the namespace (stopped at lab cleanup)."""
        full_env = dict(os.environ)
        full_env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO_ROOT), full_env.get("PYTHONPATH", "")]))
        full_env["PYTHONUNBUFFERED"] = "1"
        full_env.update(env or {})
        process = NsProcess(self.exec_args(*args), env=full_env)
        self.lab.processes.append(process)
        return process

    def python(self, *args: str, env: dict[str, str] | None = None) -> NsProcess:
        """Start ``python ARGS...`` (this interpreter, repo on PYTHONPATH) inside the namespace."""
        return self.popen(sys.executable, *args, env=env)

    def __repr__(self) -> str:
        return f"Namespace({self.name!r})"


class NetnsLab:
    """Owner of test namespaces, links and processes; cleans all of it up on exit."""

    def __init__(self) -> None:
        self.namespaces: list[Namespace] = []
        self.processes: list[NsProcess] = []

    def __enter__(self) -> NetnsLab:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def namespace(self, tag: str = "ns", multicast_lo: bool = True) -> Namespace:
        """Create a uniquely named namespace with ``lo`` up (and multicast enabled on it)."""
        if not self.namespaces:
            remove_stale_namespaces()
        name = f"{PREFIX}-{os.getpid()}-{next(_counter)}-{tag}"[:60]
        _check(_ip("netns", "add", name))
        ns = Namespace(self, name)
        self.namespaces.append(ns)
        ns.ip("link", "set", "lo", "up")
        if multicast_lo:
            ns.ip("link", "set", "lo", "multicast", "on")
        return ns

    def veth(
        self,
        a: Namespace,
        b: Namespace,
        addr_a: str | None = None,
        addr_b: str | None = None,
        name_a: str | None = None,
        name_b: str | None = None,
    ) -> tuple[str, str]:
        """Link two namespaces with a veth pair created inside them (never on the host).

        Returns the two interface addresses (without prefix). Default addresses are a fresh
        ``10.<pid % 200 + 20>.<n>.1/24`` and ``.2/24``; IPv6 ones are added without duplicate
        address detection (usable at once).
        """
        if addr_a is None or addr_b is None:
            subnet = self._subnet()
            addr_a, addr_b = addr_a or f"{subnet}.1/24", addr_b or f"{subnet}.2/24"
        name_a = name_a or self._free_name(a, "veth")
        name_b = name_b or self._free_name(b, "veth")
        a.ip("link", "add", name_a, "type", "veth", "peer", "name", name_b, "netns", b.name)
        for ns, dev, addr in ((a, name_a, addr_a), (b, name_b, addr_b)):
            ns.ip("addr", "add", addr, "dev", dev, *(("nodad",) if ":" in addr else ()))
            ns.ip("link", "set", dev, "multicast", "on")
            ns.ip("link", "set", dev, "up")
            ns.addresses.append(addr)
        return addr_a.split("/")[0], addr_b.split("/")[0]

    def bridge(self, members: Sequence[Namespace], subnet: str | None = None) -> list[str]:
        """Put ``members`` on one Ethernet segment: a bridge in its own switch namespace.

        Each member gets a veth ``vethN`` with address ``<subnet>.<k+1>/24``. Returns the
        member addresses in order (without prefix).
        """
        subnet = subnet or self._subnet()
        switch = self.namespace("switch")
        switch.ip("link", "add", "br0", "type", "bridge")
        switch.ip("link", "set", "br0", "up")
        addresses = []
        for k, member in enumerate(members):
            port = f"port{k}"
            dev = self._free_name(member, "veth")
            switch.ip("link", "add", port, "type", "veth", "peer", "name", dev, "netns", member.name)
            switch.ip("link", "set", port, "master", "br0")
            switch.ip("link", "set", port, "up")
            addr = f"{subnet}.{k + 1}/24"
            member.ip("addr", "add", addr, "dev", dev)
            member.ip("link", "set", dev, "multicast", "on")
            member.ip("link", "set", dev, "up")
            member.addresses.append(addr)
            addresses.append(addr.split("/")[0])
        return addresses

    @staticmethod
    def _free_name(ns: Namespace, stem: str) -> str:
        existing = ns.ip("-o", "link", "show").stdout
        for k in itertools.count():
            candidate = f"{stem}{k}"
            if f" {candidate}@" not in existing and f" {candidate}:" not in existing:
                return candidate
        raise AssertionError("unreachable")

    @staticmethod
    def _subnet() -> str:
        return f"10.{os.getpid() % 200 + 20}.{next(_subnets) % 250}"

    def close(self) -> None:
        """Stop every process (SIGTERM, then SIGKILL), then delete every namespace."""
        for process in reversed(self.processes):
            try:
                process.stop(timeout=3.0)
            except Exception:  # cleanup goes on
                process.kill()
        self.processes.clear()
        for ns in reversed(self.namespaces):
            _kill_inside(ns.name)  # children the processes left behind
            _ip("netns", "del", ns.name)
        self.namespaces.clear()


@pytest.fixture
def netns_lab() -> Iterator[NetnsLab]:
    """A :class:`NetnsLab` for one test (skips when namespaces are unavailable)."""
    require_netns()
    with NetnsLab() as lab:
        yield lab
