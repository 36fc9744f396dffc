"""A UDP relay that delays every datagram by a random time: link jitter without tc netem.

    python -m tests.deploy.relay --listen 0.0.0.0:9200 --to 127.0.0.1:9103 --jitter 0.02 --seed 1

Each datagram is forwarded once, ``uniform(0, jitter)`` seconds after it arrived (so datagrams
overtake each other, as on a jittery link). Prints one JSON line when listening and one with
counts when stopped (SIGTERM).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import random
import signal
import socket
from collections.abc import Sequence
from typing import Any


class _Relay(asyncio.DatagramProtocol):
    def __init__(self, to: tuple[str, int], jitter_s: float, rng: random.Random) -> None:
        self.to = to
        self.jitter_s = jitter_s
        self.rng = rng
        self.forwarded = 0
        self.transport: asyncio.DatagramTransport | None = None
        self.out = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.out.setblocking(False)

    def connection_made(self, transport: Any) -> None:
        self.transport = transport

    def datagram_received(self, data: bytes, addr: tuple[str, int]) -> None:
        delay = self.rng.uniform(0.0, self.jitter_s)
        asyncio.get_running_loop().call_later(delay, self._forward, data)

    def _forward(self, data: bytes) -> None:
        try:
            self.out.sendto(data, self.to)
            self.forwarded += 1
        except OSError:
            pass


def _address(text: str) -> tuple[str, int]:
    host, _, port = text.rpartition(":")
    return host, int(port)


async def _main(args: argparse.Namespace) -> int:
    loop = asyncio.get_running_loop()
    relay = _Relay(_address(args.to), args.jitter, random.Random(args.seed))
    transport, _ = await loop.create_datagram_endpoint(lambda: relay, local_addr=_address(args.listen))
    stop = asyncio.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    print(json.dumps({"event": "listening", "listen": args.listen, "to": args.to}), flush=True)
    await stop.wait()
    transport.close()
    print(json.dumps({"event": "stopped", "forwarded": relay.forwarded}), flush=True)
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--listen", required=True, help="HOST:PORT to receive on")
    parser.add_argument("--to", required=True, help="HOST:PORT to forward to")
    parser.add_argument("--jitter", type=float, default=0.02, help="maximum added delay, seconds")
    parser.add_argument("--seed", type=int, default=0)
    return asyncio.run(_main(parser.parse_args(argv)))


if __name__ == "__main__":
    raise SystemExit(main())
