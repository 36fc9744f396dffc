"""``batteur ls``: list the nodes of a rig with their health.

Nodes are found by zeroconf (or given with ``--node HOST:PORT``); each is sent
a Hello and answers with its Health. Exit code 0 when every listed node
answered, 1 otherwise (so ``batteur ls --node 127.0.0.1:9103`` is a
healthcheck).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import sys
from collections.abc import Sequence

from batteur.tools.nodes import Target, bind_address, find_targets
from batteur.tools.nodes import target_networks as _networks
from common.arg_types import seconds
from common.messages import PROTOCOL_VERSION, Health, Hello, OscMessage
from common.transport import UdpEndpoint


async def query_health(targets: Sequence[Target], timeout_s: float) -> dict[str, Health]:
    """Send a Hello to each target; collect the Health answers by source address within ``timeout_s``."""
    answers: dict[str, Health] = {}
    endpoint = await UdpEndpoint.open(bind_address(targets), allow=_networks(targets) or None)
    done = asyncio.Event()

    def on_message(message: OscMessage, source: str) -> None:
        if isinstance(message, Health):
            answers[source] = message
            if len(answers) >= len(targets):
                done.set()

    endpoint.set_handler(on_message)
    hello = Hello(role="cli", node_id="batteur-ls", protocol=PROTOCOL_VERSION, osc_port=endpoint.port)
    for target in targets:
        endpoint.send(hello, target.address)
    try:
        await asyncio.wait_for(done.wait(), timeout_s)
    except TimeoutError:
        pass
    endpoint.close()
    return answers


def _row(target: Target, health: Health | None) -> dict[str, object]:
    row: dict[str, object] = {"role": target.role, "node_id": target.node_id, "address": target.address}
    if health is None:
        row["status"] = "no answer"
        return row
    row.update(
        role=health.role, node_id=health.node_id, status="ok", protocol=health.protocol,
        rate_hz=round(health.rate_hz, 1), target_rate_hz=health.target_rate_hz, overruns=health.overruns,
        messages_in=health.messages_in, messages_out=health.messages_out, dropped=health.dropped,
        late=health.late, peers=health.peers,
    )
    return row


async def _run(opts: argparse.Namespace) -> int:
    targets = await find_targets(opts.node, opts.browse, opts.interface)
    if not targets:
        print("batteur ls: no nodes found", file=sys.stderr)
        return 1
    answers = await query_health(targets, opts.timeout)
    rows = []
    for target in targets:
        health = next((h for src, h in answers.items() if src.rsplit(":", 1)[-1] == str(target.port)), None)
        rows.append(_row(target, health))
    if opts.json:
        print(json.dumps(rows, indent=2))
    else:
        print(f"{'role':<12} {'node id':<28} {'address':<22} {'status':<10} {'rate Hz':>8} {'dropped':>8} {'peers':>5}")
        for r in rows:
            print(f"{r['role']!s:<12} {r['node_id']!s:<28} {r['address']!s:<22} {r['status']!s:<10} "
                  f"{r.get('rate_hz', '')!s:>8} {r.get('dropped', '')!s:>8} {r.get('peers', '')!s:>5}")
    return 0 if all(r["status"] == "ok" for r in rows) else 1


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="batteur ls", description=__doc__.split("\n\n")[0] if __doc__ else None)
    parser.add_argument("--node", action="append", default=[], metavar="HOST:PORT",
                        help="ask this node instead of browsing (repeatable)")
    parser.add_argument("--interface", action="append", default=[],
                        help="interface to browse on (repeatable; default loopback)")
    parser.add_argument("--browse", type=seconds, default=3.0, help="seconds to browse for nodes (default 3)")
    parser.add_argument("--timeout", type=seconds, default=2.0, help="seconds to wait for health answers (default 2)")
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    opts = parser.parse_args(argv)
    try:
        return asyncio.run(_run(opts))
    except ValueError as exc:
        print(f"batteur ls: {exc}", file=sys.stderr)
        return 2
