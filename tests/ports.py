"""Loopback ports for tests that hand a port number to another program.

A port found by binding port 0 and closing the socket is the kernel's to hand out again: the next program
that binds port 0 may get it. In CI a graphics node's OSCQuery server (bound to port 0) took the HTTP port
its test had just found that way, and the node stopped with "Address already in use". The kernel hands out
port 0 only from its ephemeral range (``/proc/sys/net/ipv4/ip_local_port_range``), so a port chosen below
that range and free now stays free for the program the test starts.

The suite runs on several processes (pytest-xdist); each worker picks from its own slice of the range, so two
workers never hand the same port to programs starting at the same moment (a port both found free).
"""

from __future__ import annotations

import os
import random
import socket
from pathlib import Path

PORT_RANGE_FILE = Path("/proc/sys/net/ipv4/ip_local_port_range")
LOWEST_PORT = 10000
"""No test port below this (keeps clear of well-known and registered service ports people run)."""

_given: set[int] = set()
_random = random.Random()  # its own generator: a test seeding `random` must not make two suites pick alike


def _ephemeral_low() -> int:
    """First port of the kernel's ephemeral range (32768 if the file cannot be read)."""
    try:
        return int(PORT_RANGE_FILE.read_text().split()[0])
    except (OSError, ValueError, IndexError):
        return 32768


def _worker_slice(low: int, high: int) -> tuple[int, int]:
    """This pytest-xdist worker's share ``[low, high]`` of the ports ``low``-``high`` (all of them without
    xdist): worker ``gwN`` of ``PYTEST_XDIST_WORKER_COUNT`` takes the N-th equal slice."""
    worker = os.environ.get("PYTEST_XDIST_WORKER", "")
    try:
        index, count = int(worker.removeprefix("gw")), int(os.environ["PYTEST_XDIST_WORKER_COUNT"])
    except (KeyError, ValueError):
        return low, high
    if not 0 <= index < count:
        return low, high
    width = (high - low + 1) // count
    return low + index * width, low + (index + 1) * width - 1


def _bindable(port: int, kind: int, host: str) -> bool:
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, kind) as probe:
        try:
            probe.bind((host, port))
        except OSError:
            return False
    return True


def free_ports(count: int, kind: int = socket.SOCK_DGRAM, host: str = "127.0.0.1") -> list[int]:
    """``count`` consecutive ports free on ``host`` for ``kind`` (``socket.SOCK_DGRAM`` or ``SOCK_STREAM``),
    below the ephemeral range, in this worker's slice of it and not given before in this process."""
    low, high = _worker_slice(LOWEST_PORT, _ephemeral_low() - 1)
    high -= count - 1
    if high <= low:
        raise AssertionError(f"the ephemeral range starts too low ({_ephemeral_low()}) for test ports")
    for _ in range(500):
        base = _random.randint(low, high)
        ports = list(range(base, base + count))
        if _given.isdisjoint(ports) and all(_bindable(port, kind, host) for port in ports):
            _given.update(ports)
            return ports
    raise AssertionError(f"no {count} free ports on {host} below the ephemeral range")


def free_port(kind: int = socket.SOCK_DGRAM, host: str = "127.0.0.1") -> int:
    """A port free on ``host`` for ``kind``, which no program binding port 0 will be given meanwhile."""
    return free_ports(1, kind, host)[0]
