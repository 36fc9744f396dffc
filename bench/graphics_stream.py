"""Pose stream bandwidth: OSC /batteur/pose into the graphics node, JSON frames out to each page.

Measures the bytes of real messages (encoded OSC datagrams; WebSocket text
frames received by a client of a live :class:`ViewServer` over loopback) for
the synthetic drummer (23 links), physics' 57-DOF drummer as it publishes
itself (21 body links + 17 kit links, moving through random postures by the
editor's forward kinematics) and a 60-link body. Prints figures; asserts nothing.

    python bench/graphics_stream.py [--seconds S] [--rate HZ]    # about 3 x (S + 0.5) s: 12 s by default
"""

from __future__ import annotations

import argparse
import asyncio
import time
from collections.abc import Sequence

import numpy as np
from websockets.asyncio.client import connect

from common.arg_types import hertz, seconds
from common.messages import Pose, Skeleton, encode
from services.graphics.core import GraphicsCore, GraphicsSettings
from services.graphics.figure import synthetic_performance
from services.graphics.poser import rest_poser
from services.graphics.server import ViewServer


async def measure(names: list[str], values: np.ndarray, seconds: float, rate: float) -> tuple[float, float, int]:
    """(websocket bytes/s per page, frames/s received, OSC pose bytes per datagram), per second of poses sent (one
    period, ``1/rate`` s, each: a short ``seconds`` still sends the first pose)."""
    core = GraphicsCore(GraphicsSettings(latency=0.0, clock="rig", rate_hz=rate))
    server = ViewServer(core)
    port = await server.start("127.0.0.1", 0)
    core.handle(Skeleton(layout=1, names=tuple(names)), 0.0, "bench")
    received = [0, 0]

    async def client() -> None:
        async with connect(f"ws://127.0.0.1:{port}/ws", max_size=None) as ws:
            async for message in ws:
                if '"type":"frame"' in str(message)[:20]:
                    received[0] += len(message)
                    received[1] += 1

    task = asyncio.create_task(client())
    await asyncio.sleep(0.3)
    start = time.monotonic()
    k = 0
    osc_bytes = 0
    while (now := time.monotonic() - start) < seconds:
        frame = values[k % len(values)]
        pose = Pose(time=now, layout=1, values=tuple(float(v) for v in frame.ravel()))
        osc_bytes = len(encode(pose))
        core.handle(pose, now, "bench")
        core.step(now)
        k += 1
        await asyncio.sleep(max(0.0, (k / rate) - (time.monotonic() - start)))
    await asyncio.sleep(0.2)
    task.cancel()
    await server.close()
    sent_s = k / rate  # not ``seconds``: 1 ms sent one pose, its frame counted as "1000 frames/s"
    return received[0] / sent_s, received[1] / sent_s, osc_bytes


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=seconds, default=3.0,
                        help="streaming time per body measured, seconds (default 3)")
    parser.add_argument("--rate", type=hertz, default=60.0, help="pose and view rate, Hz, 1 to 240 (default 60)")
    return parser


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    from pydantic import ValidationError

    from common.datafile import first_error

    parser = build_parser()
    args = parser.parse_args(argv)
    try:  # the graphics node's own limits, before any server starts
        GraphicsSettings(latency=0.0, clock="rig", rate_hz=args.rate)
    except ValidationError as exc:
        parser.error(f"--rate {args.rate:g}: {first_error(exc)}")
    return args


def main(argv: Sequence[str] | None = None) -> None:
    args = parse_args(argv)
    sequence, _ = synthetic_performance(duration=2.0, rate_hz=60.0)
    big_names = [f"link{i}" for i in range(60)]
    big = np.tile(sequence.values, (1, 3, 1))[:, :60]
    poser = rest_poser()  # physics' drummer: its 21 body links, plus 17 kit links as physics publishes them
    rng = np.random.default_rng(0)
    kit = np.tile([0.3, 0.5, 0.8, 0.0, 0.0, 0.0, 1.0], (17, 1))
    drummer = np.array([np.vstack([poser.pose(poser.angles + 0.05 * np.sin(k / 10 + rng.uniform(0, 6, 57))), kit])
                        for k in range(120)])
    drummer_names = poser.names + [f"kit.part{i}" for i in range(17)]
    for label, names, values in (("synthetic drummer, 23 links", sequence.names, sequence.values),
                                 ("physics' 57-DOF drummer, 21 body + 17 kit links", drummer_names, drummer),
                                 ("a 60-link body", big_names, big)):
        ws_rate, fps, osc = asyncio.run(measure(list(names), values, args.seconds, args.rate))
        print(f"{label}:")
        print(f"  OSC in:  {osc} B/datagram x {args.rate:g} Hz = {osc * args.rate / 1024:6.1f} KiB/s")
        print(f"  WebSocket out per page: {ws_rate / 1024:6.1f} KiB/s ({fps:.1f} frames/s, "
              f"{ws_rate / max(fps, 1e-9):.0f} B/frame, JSON)")


if __name__ == "__main__":
    main()
