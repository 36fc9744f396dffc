"""Interaction benchmark: contact-in to impact-out latency and sustained impacts per second.

Prints figures, asserts nothing (timing on a shared machine is noisy; compare
the figures of one run with each other). Three measurements:

1. core only: wall time of ``InteractionCore.handle`` for a contact that starts
   an impact (no sockets), p50/p99, and impacts per second through the core;
2. loopback: the interaction node started as its own process (as in the
   rig), a client sending ``/batteur/contact`` over UDP and receiving the
   ``/batteur/impact`` the node sends to "sound": round-trip wall time from
   the contact's send to the first copy of its impact, p50/p99/max (goal: p99
   under 1 ms);
3. sustained: contacts sent as fast as the node keeps up (a bounded number in
   flight), impacts per second de-duplicated at the receiver, over a few seconds.

    python bench/interaction_bench.py [--samples 2000] [--seconds 3] [--copies 5]   # about 10 s
"""

from __future__ import annotations

import argparse
import os
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from common.arg_types import count, seconds  # noqa: E402
from common.dedupe import Deduplicator  # noqa: E402
from common.kit import load_kit  # noqa: E402
from common.messages import Contact, Impact, decode, encode  # noqa: E402
from common.messages.interaction import InteractionStats, StatsGet  # noqa: E402
from services.interaction.config import InteractionConfig, RedundancyConfig, save_config  # noqa: E402
from services.interaction.core import InteractionCore  # noqa: E402
from tests.ports import free_port  # noqa: E402  (below the ephemeral range: no port-0 bind takes it meanwhile)

INSTRUMENTS = ("snare", "hightom", "midtom", "floortom", "ride", "crash", "hihat", "splash", "china", "cowbell")
SLOT = 0.01
"""Contact i carries rig time i * SLOT: the impact's time tells which contact it answers."""


def contact(i: int, t: float | None = None) -> Contact:
    return Contact(
        time=i * SLOT if t is None else t, step=i, instrument=INSTRUMENTS[i % len(INSTRUMENTS)], part="right_stick_tip",
        x=0.0, y=0.4, z=0.7, local_x=0.04, local_y=0.01, local_z=0.0, normal_x=0.0, normal_y=0.0,
        normal_z=1.0, normal_velocity=2.0, impulse=0.002, normal_force=400.0,
    )  # fmt: skip


def percentiles_us(values: list[float]) -> str:
    a = np.asarray(values) * 1e6
    return f"p50 {np.percentile(a, 50):7.1f} us  p99 {np.percentile(a, 99):7.1f} us  max {a.max():8.1f} us"


def bench_core(samples: int, copies: int = 5) -> float:
    # the default routes, ``copies`` each: --copies used to reach the node only
    config = InteractionConfig(redundancy=RedundancyConfig(copies=copies))
    core = InteractionCore(kit=load_kit("default"), config=config)
    contacts = [contact(i) for i in range(samples)]
    times: list[float] = []
    start = time.perf_counter()
    for i, c in enumerate(contacts):
        t0 = time.perf_counter()
        core.handle(c, c.time, "physics")
        times.append(time.perf_counter() - t0)
        core.step(c.time + 0.0005 * (i % 2))
    elapsed = time.perf_counter() - start
    rate = samples / elapsed
    print(f"core only       handle(contact) -> impact: {percentiles_us(times)}")
    print(f"core only       {rate:9.0f} impacts/s (handle + step, 2 routes x {core.config.redundancy.copies} copies)")
    return rate


def start_node(copies: int, sound_port: int, config_dir: Path, epoch: float) -> tuple[subprocess.Popen[bytes], int]:
    path = config_dir / "interaction.yaml"
    config = InteractionConfig(redundancy=RedundancyConfig(copies=copies), routes=[{"to": "sound", "ends": False}])  # type: ignore[list-item]
    save_config(config, path)
    port = free_port()
    cmd = [
        sys.executable, "-m", "services.interaction.node", "--port", str(port), "--no-discovery",
        "--clock-master", "self", "--peer", f"sound=127.0.0.1:{sound_port}", "--interaction-config", str(path),
        "--log-level", "WARNING", "--epoch", repr(epoch),
    ]  # fmt: skip
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    return proc, port


def receiver() -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        sock.setsockopt(socket.SOL_SOCKET, getattr(socket, "SO_RCVBUFFORCE", 33), 16 * 1024 * 1024)
    except OSError:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 16 * 1024 * 1024)
    sock.bind(("127.0.0.1", 0))
    return sock


def impacts_in(sock: socket.socket, timeout: float) -> list[tuple[str, Impact]]:
    sock.settimeout(timeout)
    out: list[tuple[str, Impact]] = []
    try:
        data, addr = sock.recvfrom(65536)
    except (TimeoutError, BlockingIOError):
        return out
    sock.setblocking(False)
    while True:
        out += [(f"{addr[0]}:{addr[1]}", m) for m in decode(data).messages if isinstance(m, Impact)]
        try:
            data, addr = sock.recvfrom(65536)
        except BlockingIOError:
            return out


def wait_ready(
    send: socket.socket, sound: socket.socket, node: tuple[str, int], epoch: float, timeout: float = 20.0
) -> int:
    """Send warm-up contacts until impacts come back; the next free contact index."""
    i = 0
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        send.sendto(encode(contact(i, time.time() - epoch)), node)
        i += 1
        if impacts_in(sound, 0.05):
            time.sleep(0.2)
            impacts_in(sound, 0.01)  # drain the copies
            return i + 1
    raise RuntimeError("the interaction node did not answer")


def node_latency(send: socket.socket, node: tuple[str, int]) -> tuple[float, float]:
    """The node's own latency figures (/batteur/interaction/stats), seconds."""
    send.settimeout(2.0)
    send.sendto(encode(StatsGet()), node)
    while True:
        data, _ = send.recvfrom(65536)
        for message in decode(data).messages:
            if isinstance(message, InteractionStats):
                send.settimeout(None)
                return message.latency_p50, message.latency_p99


def bench_loopback(samples: int, seconds: float, copies: int) -> None:
    sound = receiver()
    sound_port = sound.getsockname()[1]
    send = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    epoch = time.time() - 1000.0  # the node's rig clock: Unix time - epoch (it is its own clock master)
    with tempfile.TemporaryDirectory() as tmp:
        proc, port = start_node(copies, sound_port, Path(tmp), epoch)
        node = ("127.0.0.1", port)
        try:
            first = wait_ready(send, sound, node, epoch)
            # 1. latency: one contact at a time, wait for its impact
            dedupe = Deduplicator()
            latencies: list[float] = []
            lost = 0
            for i in range(first, first + samples):
                t0 = time.perf_counter()
                stamp = time.time() - epoch  # the contact's time on the node's rig clock
                send.sendto(encode(contact(i, stamp)), node)
                got = False
                deadline = t0 + 0.5
                while not got and time.perf_counter() < deadline:
                    for source, impact in impacts_in(sound, 0.5):
                        if dedupe.accept_message(source, impact) and abs(impact.time - stamp) < 1e-5:
                            latencies.append(time.perf_counter() - t0)
                            got = True
                lost += not got
                time.sleep(0.0005)
            print(
                f"loopback UDP    contact -> impact ({copies} copies): {percentiles_us(latencies)}  ({lost} timeouts)"
            )
            node_p50, node_p99 = node_latency(send, node)
            print(
                f"node's own      contact time -> impact out (rig clock, incl. transit in): "
                f"p50 {node_p50 * 1e6:7.1f} us  p99 {node_p99 * 1e6:7.1f} us"
            )
            time.sleep(0.1)
            impacts_in(sound, 0.01)
            # 2. sustained: keep at most `window` contacts in flight
            window = 64
            start_index = first + samples + 10
            sent = received = 0
            dedupe = Deduplicator(window=65536)
            begin = time.perf_counter()
            while time.perf_counter() - begin < seconds:
                while sent - received < window:
                    send.sendto(encode(contact(start_index + sent)), node)
                    sent += 1
                for source, impact in impacts_in(sound, 0.05):
                    received += dedupe.accept_message(source, impact)
            elapsed = time.perf_counter() - begin
            print(
                f"loopback UDP    sustained: {received / elapsed:9.0f} impacts/s de-duplicated "
                f"({received} in {elapsed:.2f} s, {window} in flight, {copies} copies each)"
            )
        finally:
            proc.terminate()
            try:
                proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
            send.close()
            sound.close()
            if proc.returncode not in (0, -15) and proc.stderr is not None:
                print(proc.stderr.read().decode(errors="replace")[-2000:], file=sys.stderr)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--samples", type=count, default=2000, help="latency samples (default 2000)")
    parser.add_argument("--seconds", type=seconds, default=3.0, help="sustained-rate duration, s (default 3)")
    parser.add_argument("--copies", type=count, default=5,
                        help="redundant copies per impact, as interaction's config allows (default 5)")
    return parser


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    from pydantic import ValidationError

    from common.datafile import first_error

    parser = build_parser()
    args = parser.parse_args(argv)
    try:  # the node's own limit, before it is started
        RedundancyConfig(copies=args.copies)
    except ValidationError as exc:
        parser.error(f"--copies {args.copies}: {first_error(exc)}")
    return args


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    print(f"interaction bench on {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f}")
    bench_core(args.samples, args.copies)
    bench_loopback(args.samples, args.seconds, args.copies)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
