"""Loopback transport figures: one-way latency between two processes, and burst loss.

The sender (this process) and a receiver (a child process running this script
with ``--receive``) each open a :class:`common.transport.UdpEndpoint` on
127.0.0.1. Both read ``CLOCK_MONOTONIC``, which Linux shares between
processes, so a message carrying its send time gives the one-way latency
directly (encode, socket, kernel, asyncio wake-up, decode, handler).

1. latency: ``--pings`` ClockPing messages paced at ``--pace-hz``; p50/p99/max.
   Interleaved with them, the same number of 8-byte datagrams go to a third
   process that reads a plain blocking socket: the floor this machine's
   scheduler allows, measured under the same load (the machine is shared).
2. burst: ``--burst`` Impact messages sent back to back while the receiving
   process is busy (its event loop blocked for ``--busy`` seconds, as by a long
   step), so the whole burst must wait in the kernel: into an endpoint with
   the transport's receive buffer, and into one with the kernel's default
   buffer (what an untuned socket loses); messages lost in each.

    python bench/transport_bench.py              # about 10 s; goal: p99 < 1 ms, no loss
"""

from __future__ import annotations

import argparse
import asyncio
import gc
import json
import os
import socket
import statistics
import struct
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from common.arg_types import count, hertz, seconds  # noqa: E402
from common.messages import ClockPing, Hello, Impact, OscMessage  # noqa: E402
from common.transport import DEFAULT_RCVBUF, UdpEndpoint  # noqa: E402

KERNEL_DEFAULT_RCVBUF = 212_992  # net.core.rmem_default on common Linux systems, bytes


def impact(seq: int) -> Impact:
    return Impact(seq=seq, time=12.5, instrument="snare", zone="centre", r=0.3, theta=0.4, velocity=3.2,
                  impulse=0.02, peak_force=300.0, duration=0.004, part="right_stick_tip")


def raw_receive() -> None:
    """Child process: a plain blocking socket; one-way latency of 8-byte datagrams, no OSC, no asyncio."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    print(json.dumps({"port": sock.getsockname()[1]}), flush=True)
    latencies: list[float] = []
    while True:
        data, _ = sock.recvfrom(64)
        now = time.monotonic()
        if data == b"done":
            break
        latencies.append(now - struct.unpack("d", data)[0])
    print(json.dumps({"latencies": latencies}), flush=True)
    sock.close()


async def receive(rcvbuf_default: int) -> None:
    """Child process: print the two ports, collect until told 'done', print the results as JSON."""
    tuned = await UdpEndpoint.open(rcvbuf_bytes=rcvbuf_default)
    untuned = await UdpEndpoint.open(rcvbuf_bytes=KERNEL_DEFAULT_RCVBUF)
    latencies: list[float] = []
    bursts = {"tuned": 0, "untuned": 0}
    done = asyncio.Event()

    def on_tuned(message: OscMessage, source: str) -> None:
        now = time.monotonic()
        if isinstance(message, ClockPing):
            latencies.append(now - message.t_send)
        elif isinstance(message, Impact):
            bursts["tuned"] += 1
        elif isinstance(message, Hello) and message.node_id == "done":
            done.set()
        elif isinstance(message, Hello) and message.node_id == "busy":
            time.sleep(message.osc_port / 1000)  # block the loop: datagrams queue in the kernel

    def on_untuned(message: OscMessage, source: str) -> None:
        if isinstance(message, Impact):
            bursts["untuned"] += 1

    tuned.set_handler(on_tuned)
    untuned.set_handler(on_untuned)
    gc.collect()
    gc.freeze()  # as common.runtime.run_node does once a node has started
    print(json.dumps({"tuned": tuned.port, "untuned": untuned.port,
                      "rcvbuf": [tuned.rcvbuf_bytes, untuned.rcvbuf_bytes]}), flush=True)
    await done.wait()
    await asyncio.sleep(0.5)  # stragglers
    print(json.dumps({"latencies": latencies, "bursts": bursts,
                      "drops": tuned.stats.dropped_total + untuned.stats.dropped_total}), flush=True)
    tuned.close()
    untuned.close()


async def send(
    child: subprocess.Popen[str], raw_child: subprocess.Popen[str], pings: int, pace_hz: float, burst: int,
    busy_s: float,
) -> dict[str, object]:
    assert child.stdout is not None and raw_child.stdout is not None
    ports = json.loads(child.stdout.readline())
    raw_target = ("127.0.0.1", json.loads(raw_child.stdout.readline())["port"])
    raw_sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    tuned = f"127.0.0.1:{ports['tuned']}"
    untuned = f"127.0.0.1:{ports['untuned']}"
    ep = await UdpEndpoint.open()
    period = 1.0 / pace_hz
    start = time.monotonic()
    for seq in range(pings):
        deadline = start + seq * period
        delay = deadline - time.monotonic()
        if delay > 0:
            await asyncio.sleep(delay)
        ep.send(ClockPing(node_id="bench", seq=seq, t_send=time.monotonic()), tuned)
        await asyncio.sleep(period / 2)
        raw_sock.sendto(struct.pack("d", time.monotonic()), raw_target)
    raw_sock.sendto(b"done", raw_target)
    raw_results = json.loads(await asyncio.to_thread(raw_child.stdout.readline))
    raw_sock.close()
    await asyncio.sleep(0.2)
    burst_times = {}
    for name, target in (("tuned", tuned), ("untuned", untuned)):
        ep.send(Hello(role="bench", node_id="busy", protocol=1, osc_port=int(busy_s * 1000)), tuned)
        await asyncio.sleep(0.05)
        t0 = time.perf_counter()
        for seq in range(burst):
            ep.send(impact(seq), target)
        burst_times[name] = time.perf_counter() - t0
        await asyncio.sleep(busy_s + 0.5)
    ep.send(Hello(role="bench", node_id="done", protocol=1, osc_port=0), tuned)
    results: dict[str, object] = json.loads(await asyncio.to_thread(child.stdout.readline))
    results["rcvbuf"] = ports["rcvbuf"]
    results["raw_latencies"] = raw_results["latencies"]
    results["burst_send_s"] = burst_times
    ep.close()
    return results


MAX_BUSY_S = 65.535
"""The receiver is told how long to be busy in a Hello's port field (milliseconds, at most 65535)."""
MAX_RCVBUF = 2**31 - 1
"""The largest receive buffer a socket option can ask for (a C int), bytes."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--pings", type=count, default=3000, help="latency samples (default 3000)")
    parser.add_argument("--pace-hz", type=hertz, default=1000.0, help="latency send rate, Hz (default 1000)")
    parser.add_argument("--burst", type=count, default=10_000, help="messages per burst (default 10000)")
    parser.add_argument("--busy", type=seconds, default=1.0,
                        help=f"seconds the receiver is busy during each burst, at most {MAX_BUSY_S:g} (default 1)")
    parser.add_argument("--rcvbuf", type=count, default=DEFAULT_RCVBUF,
                        help=f"tuned receive buffer to ask for, bytes (default {DEFAULT_RCVBUF})")
    parser.add_argument("--realtime", action="store_true",
                        help="run all three processes at SCHED_FIFO priority 10 (needs root): measures the transport "
                        "rather than a busy machine's scheduler")
    parser.add_argument("--receive", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--raw-receive", action="store_true", help=argparse.SUPPRESS)
    return parser


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    """The options, checked before the child processes start (a bad value otherwise fails half-way through)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.busy > MAX_BUSY_S:
        parser.error(f"--busy {args.busy:g}: at most {MAX_BUSY_S:g} seconds")
    if args.rcvbuf > MAX_RCVBUF:
        parser.error(f"--rcvbuf {args.rcvbuf}: at most {MAX_RCVBUF} bytes")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    if args.receive:
        asyncio.run(receive(args.rcvbuf))
        return 0
    if args.raw_receive:
        raw_receive()
        return 0
    realtime = False
    if args.realtime:
        try:  # children inherit the policy
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(10))
            realtime = True
        except (OSError, AttributeError) as exc:
            print(f"--realtime: cannot set SCHED_FIFO ({exc}); running at normal priority")
    child = subprocess.Popen(
        [sys.executable, __file__, "--receive", "--rcvbuf", str(args.rcvbuf)], stdout=subprocess.PIPE, text=True
    )
    raw_child = subprocess.Popen([sys.executable, __file__, "--raw-receive"], stdout=subprocess.PIPE, text=True)
    try:
        results = asyncio.run(send(child, raw_child, args.pings, args.pace_hz, args.burst, args.busy))
    finally:
        for proc in (child, raw_child):
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
    lat = sorted(1e6 * x for x in results["latencies"])  # type: ignore[attr-defined]
    raw = sorted(1e6 * x for x in results["raw_latencies"])  # type: ignore[attr-defined]
    bursts: dict[str, int] = results["bursts"]  # type: ignore[assignment]
    rcvbuf: list[int] = results["rcvbuf"]  # type: ignore[assignment]
    send_s: dict[str, float] = results["burst_send_s"]  # type: ignore[assignment]
    load = os.getloadavg()[0]
    print(f"loopback transport, two processes, UdpEndpoint -> UdpEndpoint "
          f"({'SCHED_FIFO' if realtime else 'normal priority'}, load average {load:.1f} on {os.cpu_count()} CPUs)")
    for name, values in (("transport", lat), ("plain socket floor", raw)):
        if values:
            p50 = values[len(values) // 2]
            p99 = values[min(len(values) - 1, int(len(values) * 0.99))]
            verdict = ("meets" if p99 < 1000 else "MISSES") + " the p99 < 1 ms goal" if name == "transport" else ""
            print(f"one-way latency, {name}: {len(values)}/{args.pings} received at {args.pace_hz:g} Hz: "
                  f"p50 {p50:.0f} us, p99 {p99:.0f} us, max {values[-1]:.0f} us, "
                  f"mean {statistics.fmean(values):.0f} us {verdict}")
        else:
            print(f"one-way latency, {name}: no message received")
    for name, size in (("tuned", rcvbuf[0]), ("untuned", rcvbuf[1])):
        got = bursts[name]
        rate = args.burst / send_s[name] if send_s[name] > 0 else 0.0
        late = " (sent slower than the receiver was busy)" if send_s[name] > args.busy else ""
        print(f"burst of {args.burst} messages into a busy receiver, {name} receive buffer ({size} bytes): "
              f"{args.burst - got} lost, sent at {rate:,.0f} msg/s{late}")
    print(f"messages dropped as invalid: {results['drops']}")
    if not realtime and lat and lat[min(len(lat) - 1, int(len(lat) * 0.99))] > 1000:
        print("note: compare with the plain socket floor; on a busy machine the tail is the scheduler's. "
              "Rerun with --realtime (root) to measure the transport itself.")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
