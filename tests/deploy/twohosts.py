"""Two "laptops" in network namespaces: A runs physics, interaction and graphics, B runs sound.

Shared by tests/deploy/test_two_hosts.py and bench/two_hosts_bench.py. Every node listens on
0.0.0.0 with an allow-list of the test network and runs mDNS on its namespace's veth address
only; the namespaces and their links exist only for the test (tests/netns.py).
"""

from __future__ import annotations

import datetime
import json
import math
import re
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import soundfile as sf

from tests.netns import Namespace, NetnsLab, NsProcess

PORTS = {"physics": 9101, "interaction": 9102, "sound": 9103, "graphics": 9104}
LOG_TIME = re.compile(r"^(\d{4}-\d\d-\d\d \d\d:\d\d:\d\d,\d{3}) ")
OFFSET = re.compile(r"rig clock synced to \w+: offset ([+-]?\d+\.\d+) s")


def log_time(line: str) -> float | None:
    """Unix time of a log line written by the nodes' logging format (local time), or None."""
    match = LOG_TIME.match(line)
    if match is None:
        return None
    stamp = datetime.datetime.strptime(match.group(1), "%Y-%m-%d %H:%M:%S,%f")
    return stamp.timestamp()


def wait_line(proc: NsProcess, predicate: Callable[[str], bool], timeout: float, start: int = 0) -> str:
    """The first stderr line (from index ``start``) satisfying ``predicate``; AssertionError on timeout."""
    deadline = time.monotonic() + timeout
    while True:
        for line in proc.errors[start:]:
            if predicate(line):
                return line
        if time.monotonic() > deadline:
            raise AssertionError(proc.describe(f"no matching log line within {timeout:g} s"))
        if proc.popen.poll() is not None:
            raise AssertionError(proc.describe("the process ended"))
        time.sleep(0.05)


@dataclass
class TwoHosts:
    """The two namespaces, their addresses and the nodes started in them."""

    lab: NetnsLab
    a: Namespace
    b: Namespace
    addr_a: str
    addr_b: str
    epoch: float = field(default_factory=lambda: time.time())
    latency_s: float = 0.05
    procs: dict[str, NsProcess] = field(default_factory=dict)

    @classmethod
    def create(cls, lab: NetnsLab) -> TwoHosts:
        a, b = lab.namespace("lapA"), lab.namespace("lapB")
        addr_a, addr_b = lab.veth(a, b)
        return cls(lab, a, b, addr_a, addr_b)

    def node(self, name: str, role: str, *args: str, epoch_shift_s: float = 0.0, port: int | None = None,
             peers: Sequence[str] = ()) -> NsProcess:
        """Start ``batteur ROLE`` on A (physics, interaction, graphics) or B (sound) as ``name``."""
        on_b = role == "sound"
        ns, address = (self.b, self.addr_b) if on_b else (self.a, self.addr_a)
        argv = ["-m", "batteur", role, "--host", "0.0.0.0", "--allow", "10.0.0.0/8", "--interface", address,
                "--port", str(port or PORTS[role]), "--epoch", repr(self.epoch + epoch_shift_s),
                "--node-id", name, "--log-level", "INFO", "--no-oscquery", "--latency-s", repr(self.latency_s)]
        for peer in peers:
            argv += ["--peer", peer]
        proc = ns.python(*argv, *args)
        self.procs[name] = proc
        return proc

    def rig_a(self, strike_period_s: float = 0.3, interaction_peers: Sequence[str] = ()) -> None:
        """Physics (strike scene, a strike every ``strike_period_s``), interaction and graphics on A."""
        self.node("physics-a", "physics", "--scene", "strike", "--strike-period", str(strike_period_s),
                  "--strike-velocity", "3", "--pose-rate-hz", "30")
        self.node("interaction-a", "interaction", "--interaction-config", "none", peers=interaction_peers)
        self.node("graphics-a", "graphics", "--http-port", "0")

    def echo(self, ns: Namespace, role: str, pattern: str, name: str, node: str) -> NsProcess:
        """``batteur echo PATTERN --json`` against the local node of ``role`` (copies of its traffic).

        Returns once node ``node`` (the name it was started as) logs the subscription.
        """
        target = self.procs[node]
        wait_line(target, lambda s: "listening on" in s and "node" in s, 60)
        mark = len(target.errors)
        proc = ns.python("-m", "batteur", "echo", pattern, "--node", f"127.0.0.1:{PORTS[role]}", "--json")
        self.procs[name] = proc
        wait_line(target, lambda s: f"forwarding {pattern}" in s, 30, mark)
        return proc

    def nft_loss(self, ns: Namespace, percent: int) -> None:
        """Drop ``percent`` % of the UDP datagrams arriving in ``ns`` over its veth, at random (nftables)."""
        ns.run("nft", "add", "table", "inet", "btloss")
        ns.run("nft", "add", "chain", "inet", "btloss", "in", "{ type filter hook input priority 0 ; }")
        ns.run("nft", "add", "rule", "inet", "btloss", "in", "iifname", "!=", "lo", "meta", "l4proto", "udp",
               "numgen", "random", "mod", "100", "<", str(percent), "counter", "drop")

    def nft_dropped(self, ns: Namespace) -> int:
        out = ns.run("nft", "list", "table", "inet", "btloss", check=False).stdout
        match = re.search(r"counter packets (\d+)", out)
        return int(match.group(1)) if match else 0


def settle_echo(proc: NsProcess, quiet_s: float = 1.0, timeout: float = 10.0) -> None:
    """Wait until an echo process has printed nothing new for ``quiet_s`` (its output lags under load)."""
    deadline = time.monotonic() + timeout
    count = -1
    while time.monotonic() < deadline:
        now = len(proc.events())
        if now == count:
            return
        count = now
        time.sleep(quiet_s)


def impacts_from_echo(proc: NsProcess) -> list[dict[str, Any]]:
    """Unique impacts (by seq) an echo process printed, in time order."""
    unique: dict[int, dict[str, Any]] = {}
    for event in proc.events():
        if event.get("address") == "/batteur/impact":
            unique.setdefault(int(event["seq"]), event)
    return sorted(unique.values(), key=lambda e: float(e["time"]))


def last_health(proc: NsProcess, role: str, node_id: str = "") -> dict[str, Any] | None:
    """The latest Health of ``role`` (of node ``node_id`` if given) an echo process printed."""
    found = [e for e in proc.events() if e.get("address") == "/batteur/health" and e.get("role") == role
             and (not node_id or e.get("node_id") == node_id)]
    return found[-1] if found else None


def wait_health(proc: NsProcess, role: str, node_id: str, timeout: float = 15.0) -> dict[str, Any]:
    """Wait for a Health of node ``node_id`` newer than any seen so far; returns it."""
    seen = len(proc.events())
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        events = proc.events()[seen:]
        found = [e for e in events if e.get("address") == "/batteur/health" and e.get("node_id") == node_id]
        if found:
            return found[-1]
        time.sleep(0.1)
    raise AssertionError(proc.describe(f"no Health of {role} {node_id} within {timeout:g} s"))


def read_wav(path: Path) -> tuple[np.ndarray, int]:
    """Samples (frames, channels) and rate of a WAV, also one whose writer was killed before closing it.

    A killed writer leaves the header's data size at 0: the 24-bit samples after the ``data``
    chunk header are read as they are.
    """
    info = sf.info(str(path))
    if info.frames > 0 or info.subtype != "PCM_24":
        audio, rate = sf.read(str(path), dtype="float32", always_2d=True)
        return audio, int(rate)
    raw = path.read_bytes()
    start = raw.find(b"data") + 8
    body = np.frombuffer(raw[start: start + (len(raw) - start) // (3 * info.channels) * 3 * info.channels],
                         dtype=np.uint8).reshape(-1, 3)
    values = (body[:, 0].astype(np.int32) | (body[:, 1].astype(np.int32) << 8) | (body[:, 2].astype(np.int32) << 16))
    values = np.where(values >= 1 << 23, values - (1 << 24), values)
    return (values.astype(np.float32) / float(1 << 23)).reshape(-1, info.channels), int(info.samplerate)


def onsets(path: Path, frame: int = 64, refractory_s: float = 0.08) -> tuple[list[int], int]:
    """Sample indices of strike onsets in a WAV (a sharp rise of the frame peak), and the sample rate."""
    audio, rate = read_wav(path)
    mono = np.abs(audio).max(axis=1)
    n = len(mono) // frame
    if n == 0:
        return [], int(rate)
    peaks = mono[: n * frame].reshape(n, frame).max(axis=1)
    top = float(peaks.max())
    if top <= 0:
        return [], int(rate)
    found: list[int] = []
    last = -math.inf
    for k in range(2, n):
        before = float(peaks[max(0, k - 6):k - 1].max())  # an attack may straddle two frames
        rising = peaks[k] > max(0.02, 0.03 * top) and peaks[k] > 3.0 * before + 1e-4
        if rising and (k - last) * frame / rate > refractory_s:
            # refine to the first sample above a fraction of this frame's peak
            chunk = mono[(k - 1) * frame:(k + 1) * frame]
            first = int(np.argmax(chunk > max(2.0 * before, 0.1 * peaks[k])))
            found.append((k - 1) * frame + first)
            last = k
    return found, int(rate)


@dataclass
class Matching:
    """How a WAV's onsets line up with the impacts sent: ``origin`` is the rig time of sample 0."""

    origin: float
    matched: int
    onsets: int
    missed: list[float]
    errors_s: list[float]
    unmatched_s: list[float]
    """Rig times of the onsets no impact explains (seconds)."""


def match_onsets(onset_samples: Sequence[int], rate: int, impacts: Sequence[dict[str, Any]], latency_s: float,
                 duration_s: float, near_origin: float, tolerance_s: float = 0.008,
                 origin_window_s: float = 0.1, sent_after: float = -math.inf,
                 refractory_s: float = 0.08) -> Matching:
    """Find the origin that lines up most onsets with impact time + latency; count matches and misses.

    ``near_origin`` is the rig time the recording is known to start at, give or take
    ``origin_window_s`` (periodic strikes would otherwise line up at several origins).
    An impact is missed when no onset lies within ``tolerance_s`` of where it should sound although
    that place is inside the recording (away from its ends by 0.1 s) and the impact was sent to
    this sound node (its time is after ``sent_after``, e.g. when interaction found the node), and it
    does not follow another impact closer than ``refractory_s`` (the onset detector's, :func:`onsets`).
    """
    times = np.array([float(i["time"]) for i in impacts])
    # an impact within the onset detector's refractory time after another one (a stick's bounce) sounds
    # inside the earlier onset: it cannot be told apart in the WAV, so it is not counted as missed
    ordered = np.sort(times)
    shadowed = [bool(np.any((t - ordered > 0) & (t - ordered < refractory_s))) for t in times]
    best: Matching | None = None
    for n0 in onset_samples[:3]:
        for t in times:
            origin = float(t) + latency_s - n0 / rate
            if abs(origin - near_origin) > origin_window_s:
                continue
            expected = times + latency_s - origin  # seconds into the WAV
            errors = []
            unmatched = []
            for n in onset_samples:
                d = np.abs(expected - n / rate)
                if d.size and d.min() <= tolerance_s:
                    errors.append(float((n / rate) - expected[int(d.argmin())]))
                else:
                    unmatched.append(origin + n / rate)
            if best is None or len(errors) > best.matched:
                inside = [float(t2) for t2, e, hidden in zip(times, expected, shadowed, strict=True)
                          if 0.1 < e < duration_s - 0.1 and t2 > sent_after and not hidden]
                missed = [t2 for t2 in inside
                          if not any(abs(n / rate - (t2 + latency_s - origin)) <= tolerance_s for n in onset_samples)]
                best = Matching(origin, len(errors), len(onset_samples), missed, errors, unmatched)
    return best or Matching(0.0, 0, len(onset_samples), [float(t) for t in times], [],
                            [n / rate for n in onset_samples])


def wav_duration(path: Path) -> float:
    audio, rate = read_wav(path)
    return len(audio) / rate


def offset_from_log(proc: NsProcess) -> float:
    line = wait_line(proc, lambda s: OFFSET.search(s) is not None, 30.0)
    match = OFFSET.search(line)
    assert match is not None
    return float(match.group(1))


def core_start_rig_time(proc: NsProcess, epoch: float) -> float:
    """Rig time at which a non-master node's core started (its clock sync, from its log), seconds."""
    line = wait_line(proc, lambda s: OFFSET.search(s) is not None, 30.0)
    stamp = log_time(line)
    assert stamp is not None
    return stamp - epoch


def dump(obj: Any) -> str:
    return json.dumps(obj, indent=1, default=str)


def python() -> str:
    return sys.executable
