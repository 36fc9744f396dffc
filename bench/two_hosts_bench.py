"""Two "laptops" in network namespaces: one-way latency and jitter, and strikes lost on a lossy link.

    sudo python bench/two_hosts_bench.py                 # about a minute
    sudo python bench/two_hosts_bench.py --strikes 1000 --loss 5

Needs root (``ip netns``) and nftables. Everything runs inside namespaces this script creates
(tests/netns.py) and removes.

1. One-way latency A -> B through the Batteur transport (UdpEndpoint on both sides): each
   datagram carries its send time; both namespaces share the machine's clock, so arrival minus
   send time is the one-way delay. Printed for the plain veth and through a relay adding up to
   20 ms of jitter (tests/deploy/relay.py).
2. Strikes lost: the real interaction node on A turns synthetic strokes into impacts and sends
   them to a counter on B while ``--loss`` % of the datagrams arriving on B are dropped at random
   (nftables ``numgen random``). Once with redundancy off (1 copy), once with the default 4
   copies 4 ms apart. A strike is lost when none of its copies arrives.
Figures are printed, never asserted (one run on a shared machine: read them as ratios).
"""

from __future__ import annotations

import argparse
import json
import sys
import textwrap
import time
from collections.abc import Sequence
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from common.arg_types import count, seconds  # noqa: E402
from common.exit_status import report_error  # noqa: E402
from tests.deploy.twohosts import TwoHosts, impacts_from_echo, settle_echo, wait_line  # noqa: E402
from tests.netns import NetnsLab, netns_unavailable_reason  # noqa: E402

RECEIVER = textwrap.dedent("""
    import asyncio, json, signal, sys, time
    from common.messages import Impact, ClockPing
    from common.transport import UdpEndpoint
    async def main():
        delays, seqs, copies = [], set(), 0
        ep = await UdpEndpoint.open("0.0.0.0", int(sys.argv[1]), allow=["10.0.0.0/8", "127.0.0.0/8"])
        def on(m, s):
            nonlocal copies
            now = time.time()
            if isinstance(m, ClockPing):
                delays.append(now - m.t_send)
            elif isinstance(m, Impact):
                copies += 1
                seqs.add(m.seq)
        ep.set_handler(on)
        stop = asyncio.Event()
        asyncio.get_running_loop().add_signal_handler(signal.SIGTERM, stop.set)
        print(json.dumps({"event": "listening"}), flush=True)
        await stop.wait()
        print(json.dumps({"event": "done", "delays": delays, "seqs": sorted(seqs), "copies": copies}), flush=True)
    asyncio.run(main())
""")

PINGER = textwrap.dedent("""
    import asyncio, sys, time
    from common.messages import ClockPing
    from common.transport import UdpEndpoint
    async def main():
        ep = await UdpEndpoint.open("0.0.0.0", 0, allow=["10.0.0.0/8"])
        target = (sys.argv[1], int(sys.argv[2]))
        for k in range(int(sys.argv[3])):
            ep.send(ClockPing(node_id="bench", seq=k, t_send=time.time()), target)
            await asyncio.sleep(0.002)
        await asyncio.sleep(0.2)
    asyncio.run(main())
""")

FEEDER = textwrap.dedent("""
    import socket, sys, time
    from common.kit import load_kit
    from common.messages import encode
    from services.interaction.synthetic import StreamBuilder, strike
    n, gap, port = int(sys.argv[1]), float(sys.argv[2]), int(sys.argv[3])
    b = StreamBuilder(load_kit("default"), "snare")
    t0 = 1.0
    for k in range(n):
        strike(b, t0 + k * gap, velocity=3.0)
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    start = time.monotonic()
    for c in sorted(b.contacts, key=lambda c: c.step):
        wait = start + (c.time - t0) - time.monotonic()
        if wait > 0:
            time.sleep(wait)
        s.sendto(encode(c), ("127.0.0.1", port))
    time.sleep(0.3)
""")


def percentiles(values: list[float]) -> str:
    if not values:
        return "no samples"
    v = sorted(values)

    def q(p: float) -> float:
        return v[min(len(v) - 1, int(p * len(v)))] * 1e3

    mean = sum(v) / len(v)
    std = (sum((x - mean) ** 2 for x in v) / len(v)) ** 0.5
    return (f"n={len(v)}  p50 {q(0.5):.3f} ms  p99 {q(0.99):.3f} ms  max {v[-1] * 1e3:.3f} ms  "
            f"jitter (std) {std * 1e3:.3f} ms")


def one_way(rig: TwoHosts, count: int, via_relay: bool) -> list[float]:
    receiver = rig.b.python("-c", RECEIVER, "9300")
    receiver.expect(lambda e: e.get("event") == "listening", 30)
    port = 9300
    relay = None
    if via_relay:
        relay = rig.b.python("-m", "tests.deploy.relay", "--listen", "0.0.0.0:9301", "--to", "127.0.0.1:9300",
                             "--jitter", "0.02", "--seed", "3")
        relay.expect(lambda e: e.get("event") == "listening", 30)
        port = 9301
    pinger = rig.a.python("-c", PINGER, rig.addr_b, str(port), str(count))
    pinger.wait(timeout=120)
    time.sleep(0.1)
    if relay is not None:
        relay.stop()
    receiver.stop()
    done = receiver.expect(lambda e: e.get("event") == "done", 30)
    delays: list[float] = done["delays"]
    return delays


def lost_strikes(rig: TwoHosts, tmp: Path, strikes: int, gap: float, copies: int) -> tuple[int, int, int]:
    """(impacts sent, impacts received at least once, copies received) with ``copies`` redundant copies.

    What interaction sent is read on A with ``batteur echo`` (over A's loopback, where nothing is dropped).
    """
    config = tmp / f"interaction-{copies}.yaml"
    config.write_text(f"redundancy:\n  copies: {copies}\n  spacing: 0.004\n")
    receiver = rig.b.python("-c", RECEIVER, "9300")
    receiver.expect(lambda e: e.get("event") == "listening", 30)
    interaction = rig.node(f"interaction-{copies}", "interaction", "--interaction-config", str(config),
                           "--no-discovery", "--clock-master", "self", peers=[f"sound={rig.addr_b}:9300"])
    wait_line(interaction, lambda s: "listening on" in s and "node" in s, 60)
    mark = len(interaction.errors)
    echo = rig.a.python("-m", "batteur", "echo", "/batteur/impact", "--node", "127.0.0.1:9102", "--json")
    wait_line(interaction, lambda s: "forwarding /batteur/impact" in s, 30, mark)
    feeder = rig.a.python("-c", FEEDER, str(strikes), str(gap), "9102")
    feeder.wait(timeout=strikes * gap + 60)
    time.sleep(0.5)
    settle_echo(echo)
    sent = {int(e["seq"]) for e in impacts_from_echo(echo)}
    echo.stop()
    interaction.stop()
    receiver.stop()
    done = receiver.expect(lambda e: e.get("event") == "done", 30)
    got = sent & set(done["seqs"])
    return len(sent), len(got), int(done["copies"])


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--pings", type=count, default=2000,
                        help="one-way latency samples, at least 4 (default 2000; a quarter of them through the "
                             "relay)")
    parser.add_argument("--strikes", type=count, default=400, help="strikes per redundancy setting (default 400)")
    parser.add_argument("--gap", type=seconds, default=0.03, help="seconds between strikes (default 0.03)")
    parser.add_argument("--loss", type=int, default=5, help="percent of datagrams dropped on B, 0 to 100 (default 5)")
    return parser


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    """The options, checked before the namespaces are made (a bad --loss otherwise fails in nft half-way)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not 0 <= args.loss <= 100:
        parser.error(f"--loss {args.loss}: a percentage, 0 to 100")
    if args.pings < 4:  # a quarter go through the relay: fewer sent none there ("no samples")
        parser.error(f"--pings {args.pings}: at least 4 (a quarter of them go through the relay)")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    reason = netns_unavailable_reason()
    if reason is not None:
        return report_error("two_hosts_bench", reason)  # the machine cannot make the namespaces: 1
    import tempfile

    with NetnsLab() as lab, tempfile.TemporaryDirectory() as tmp:
        rig = TwoHosts.create(lab)
        print(f"laptop A {rig.addr_a}, laptop B {rig.addr_b} (veth between two network namespaces)")
        print("one-way latency A -> B, veth:            ", percentiles(one_way(rig, args.pings, False)))
        print("one-way latency A -> B, + 0-20 ms relay: ", percentiles(one_way(rig, args.pings // 4, True)))
        rig.nft_loss(rig.b, args.loss)
        for copies in (1, 4):
            sent, got, received = lost_strikes(rig, Path(tmp), args.strikes, args.gap, copies)
            print(f"{args.loss}% loss on B, {copies} cop{'y' if copies == 1 else 'ies'} per impact: "
                  f"{sent - got} of {sent} impacts lost ({100 * (sent - got) / max(sent, 1):.2f} %), "
                  f"{received} of {sent * copies} copies arrived ({args.strikes} strokes fed)")
        print(json.dumps({"nft_dropped_on_b": rig.nft_dropped(rig.b)}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
