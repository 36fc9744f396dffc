"""``batteur echo PATTERN``: print the messages whose address matches an OSC pattern.

Each node found (zeroconf, or ``--node HOST:PORT``) is sent a ``Subscribe``
and copies every matching message it sends or receives to this tool, which
renews the subscription while it runs. Stops on Ctrl-C, after ``--count``
messages or after ``--duration`` seconds.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import signal
import sys
from collections.abc import Sequence

from batteur.tools.nodes import bind_address, find_targets
from batteur.tools.nodes import target_networks as _networks
from common.arg_types import seconds
from common.messages import OscMessage, Subscribe
from common.transport import UdpEndpoint

RENEW_S = 5.0


def format_message(message: OscMessage, as_json: bool) -> str:
    if as_json:
        return json.dumps({"address": message.ADDRESS, **message.model_dump(mode="json")})
    return " ".join([message.ADDRESS, *(repr(a) if isinstance(a, str) else f"{a:g}" if isinstance(a, float)
                                         else str(a) for a in message.to_args())])


async def _run(opts: argparse.Namespace) -> int:
    targets = await find_targets(opts.node, opts.browse, opts.interface)
    if not targets:
        print("batteur echo: no nodes found", file=sys.stderr)
        return 1
    endpoint = await UdpEndpoint.open(bind_address(targets), allow=_networks(targets) or None)
    stop = asyncio.Event()
    printed = 0

    def on_message(message: OscMessage, source: str) -> None:
        nonlocal printed
        print(format_message(message, opts.json), flush=True)
        printed += 1
        if opts.count and printed >= opts.count:
            stop.set()

    endpoint.set_handler(on_message)
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    subscribe = Subscribe(pattern=opts.pattern, duration_s=RENEW_S * 2)
    deadline = None if opts.duration is None else loop.time() + opts.duration
    while not stop.is_set():
        for target in targets:
            endpoint.send(subscribe, target.address)
        wait = RENEW_S if deadline is None else min(RENEW_S, deadline - loop.time())
        if wait <= 0:
            break
        try:
            await asyncio.wait_for(stop.wait(), wait)
        except TimeoutError:
            pass
    endpoint.close()
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="batteur echo", description=__doc__.split("\n\n")[0] if __doc__ else None)
    parser.add_argument("pattern", help="OSC address pattern, e.g. '/batteur/impact' or '/batteur/*'")
    parser.add_argument("--node", action="append", default=[], metavar="HOST:PORT",
                        help="subscribe at this node instead of browsing (repeatable)")
    parser.add_argument("--interface", action="append", default=[],
                        help="interface to browse on (repeatable; default loopback)")
    parser.add_argument("--browse", type=seconds, default=3.0, help="seconds to browse for nodes (default 3)")
    parser.add_argument("--count", type=int, default=0, help="stop after this many messages (default: never)")
    parser.add_argument("--duration", type=seconds, default=None, help="stop after this many seconds")
    parser.add_argument("--json", action="store_true", help="one JSON object per line")
    opts = parser.parse_args(argv)
    if not opts.pattern.startswith("/"):
        print(f"batteur echo: pattern {opts.pattern!r} must start with '/'", file=sys.stderr)
        return 2
    try:
        return asyncio.run(_run(opts))
    except ValueError as exc:
        print(f"batteur echo: {exc}", file=sys.stderr)
        return 2
