"""``batteur echo PATTERN``: print the messages whose address matches an OSC pattern.

Each node found (zeroconf, or ``--node HOST:PORT``) is sent a ``Subscribe``
and copies every matching message it sends or receives to this tool, which
renews the subscription while it runs. A node that refuses it (table full, bad
pattern) answers ``SubscribeRefused``: echo says so once per node. Stops on
Ctrl-C, after ``--count`` messages or after ``--duration`` seconds.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import signal
import sys
from collections import OrderedDict
from collections.abc import Sequence

from batteur.errors import report_error
from batteur.tools.ls import query_health
from batteur.tools.nodes import (
    BROWSE_HELP,
    BROWSE_S,
    INTERFACE_HELP,
    INTERRUPTED,
    OutputClosed,
    Target,
    bind_address,
    browse_interfaces,
    find_targets,
    run_tool,
    target_networks,
    where_browsed,
    write_line,
)
from common.arg_types import count, seconds
from common.messages import ClockStatus, Impact, OscMessage, RawMessage, Subscribe, SubscribeRefused
from common.messages.interaction import Damping, ImpactEnd
from common.subscribe import matches, pattern_regex
from common.transport import UdpEndpoint

RENEW_S = 5.0
REDUNDANT = (Impact, ImpactEnd, Damping)
"""What interaction sends several times with one ``seq`` (its redundancy): the copies of one are one message. A
clock ping or pong's ``seq`` is its asker's: two nodes' pongs of one number are two messages."""
PROBE_S = 2.0
"""How long to wait for each node's Health before saying it does not answer."""

DESCRIPTION = """\
Print the OSC messages whose address matches PATTERN, as the nodes send or receive them.
Each node found by zeroconf (on --interface, else on the interfaces in BATTEUR_INTERFACES,
else on loopback), or given with --node, is asked to copy matching messages to this command
(a Subscribe, renewed every 5 s). One line per message:
the address, then the arguments (strings quoted); /batteur/clock/status is spelt out in words
(--json gives its fields). Messages without a model, such as those interaction sends for a
client's /batteur/interaction/message/add ('/synth/*'), are printed as they come. A message
sent several times with one sequence number (interaction sends each impact, impact end and
damping 5 times to each peer, and the node that sends it and every node that receives it copy
it here) is printed once; --copies prints every copy each node sends or receives. A node that
refuses the subscription (its table full, say) is named once on standard error, with its
reason.

Patterns (OSC 1.0): ? one character, * any run of characters but '/', [abc] [a-z] [!abc]
one character of (or not of) a set, {foo,bar} one of several strings, // any number of levels.
Examples: '/batteur/impact', '/batteur/*', '/batteur/{impact,damping}', '//health'.

Stops on Ctrl-C (exit status 130), after --count messages or after --duration seconds
(exit status 0, or 1 when no node answered)."""


def format_message(message: OscMessage, as_json: bool) -> str:
    if as_json:
        return json.dumps({"address": message.ADDRESS, **message.model_dump(mode="json")})
    if isinstance(message, ClockStatus):
        return format_clock_status(message)
    return format_args(message.ADDRESS, message.to_args())


def format_args(address: str, args: Sequence[object]) -> str:
    """The address, then the arguments: strings quoted, floats as short as they print."""
    return " ".join([address, *(repr(a) if isinstance(a, str) else f"{a:g}" if isinstance(a, float) else str(a)
                                for a in args)])


def format_raw(raw: RawMessage, as_json: bool) -> str:
    """A message without a model (one a client registered with interaction, ``message/add``, sends to its synth):
    its address and arguments as they came."""
    if as_json:
        return json.dumps({"address": raw.address,
                           "args": [a if isinstance(a, (int, float, str)) else repr(a) for a in raw.args]})
    return format_args(raw.address, raw.args)


def format_clock_status(status: ClockStatus) -> str:
    """One line a person reads: offset and uncertainty in seconds to the microsecond, then the counters."""
    master = status.master or "none found"
    if status.uncertainty_s < 0:
        estimate = f"offset {status.offset_s:+.6f} s, no estimate yet"
    else:
        estimate = (f"offset {status.offset_s:+.6f} s +/- {status.uncertainty_s:.6f} s, "
                    f"best round trip {status.round_trip_s:.6f} s")
    return (f"{status.ADDRESS} {status.node_id} {'synced' if status.synced else 'not synced'} "
            f"(master {master}): {estimate}, {status.samples} samples, {status.rejected} rejected "
            f"({status.outliers} outliers), {status.steps} steps, {status.foreign_pongs} foreign pongs")


def check_pattern(pattern: str) -> Subscribe:
    """The Subscribe for ``pattern``; ValueError saying what is wrong with it (a node would refuse it silently)."""
    pattern_regex(pattern)  # PatternError (a ValueError): unbalanced [ or {, no leading /
    return Subscribe(pattern=pattern, duration_s=RENEW_S * 2)  # ValidationError: too long


class FirstCopies:
    """Tells the first copy of a redundantly sent message (:data:`REDUNDANT`) from its repeats, by its content.

    Not by (sender, seq), the receivers' rule: echo hears one impact from every node it crosses (interaction copies
    the impact it sends, sound and graphics the one they receive), each its own sender. Its copies are alike to the
    last bit; two impacts never are (their ``seq`` differs), nor one sent mapped to one route and plain to another.
    The ``size`` latest are remembered: a rig's copies all come within tens of milliseconds."""

    def __init__(self, size: int = 4096) -> None:
        self.size = size
        self._seen: OrderedDict[tuple[object, ...], None] = OrderedDict()

    def first(self, message: OscMessage) -> bool:
        """True unless ``message`` is a redundant message already seen (every other message is a first)."""
        if not isinstance(message, REDUNDANT):
            return True
        key = (message.ADDRESS, *message.to_args())
        if key in self._seen:
            self._seen.move_to_end(key)
            return False
        self._seen[key] = None
        if len(self._seen) > self.size:
            self._seen.popitem(last=False)
        return True

    def __len__(self) -> int:
        return len(self._seen)


class Refusals:
    """The nodes that refused our subscription: each is named once (it refuses every renewal)."""

    def __init__(self, pattern: str, targets: Sequence[Target]) -> None:
        self.pattern = pattern
        self.targets = {t.socket_address: t for t in targets if t.ip}
        self.told: set[str] = set()

    def line(self, message: OscMessage, source: str) -> str | None:
        """What to say about ``message`` from ``source`` if it is a node's first refusal of our pattern, else None."""
        if not isinstance(message, SubscribeRefused) or message.pattern != self.pattern or source in self.told:
            return None
        self.told.add(source)
        target = self.targets.get(source)
        where = target.address if target is not None else source
        return f"batteur echo: node {message.node_id} at {where} refused {message.pattern}: {message.reason}"


async def _probe(targets: Sequence[Target]) -> list[Target]:
    """The targets that answer a Hello; say which do not (echo would otherwise wait in silence)."""
    reachable = [t for t in targets if t.ip]
    for target in targets:
        if not target.ip:
            print(f"batteur echo: {target.role} {target.node_id} announced no usable address "
                  f"({', '.join(target.announced) or 'none'}); skipped", file=sys.stderr)
    answers = await query_health(reachable, PROBE_S)
    answered = [t for t in reachable if t.socket_address in answers]
    for target in reachable:
        if target not in answered:
            print(f"batteur echo: {target.address} did not answer within {PROBE_S:g} s; subscribing anyway "
                  "(is a Batteur node running there?)", file=sys.stderr)
    return answered


async def _run(opts: argparse.Namespace, subscribe: Subscribe) -> int:
    interfaces, source = browse_interfaces(opts.interface)
    targets = await find_targets(opts.node, opts.browse, interfaces)
    if not targets:
        return report_error("batteur echo", f"no nodes found {where_browsed(interfaces, source)} within "
                            f"{opts.browse:g} s (start one, or give --node HOST:PORT)")
    answered = await _probe(targets)
    reachable = [t for t in targets if t.ip]
    if not reachable:
        return 1
    endpoint = await UdpEndpoint.open(bind_address(reachable), allow=target_networks(reachable))
    stop = asyncio.Event()
    printed = 0
    outcome: list[int] = []  # set by what stopped us: Ctrl-C, or the reader of our output going away
    refusals = Refusals(subscribe.pattern, reachable)
    first_copies = FirstCopies()

    def on_message(message: OscMessage, source: str) -> None:
        refused = refusals.line(message, source)
        if refused is not None:
            print(refused, file=sys.stderr)
        if stop.is_set() or not matches(opts.pattern, message.ADDRESS):
            return
        if not opts.copies and not first_copies.first(message):
            return  # a redundant copy: each node copies each of them, and each send to each peer, to us
        show(format_message(message, opts.json))

    def on_raw(raw: RawMessage, source: str) -> None:
        # no model: what interaction sends for a client's message/add (else dropped as an unknown address)
        if not stop.is_set() and matches(opts.pattern, raw.address):
            show(format_raw(raw, opts.json))

    def show(line: str) -> None:
        nonlocal printed
        try:
            write_line(line)
        except OutputClosed:  # `batteur echo ... | head`: head has what it wanted
            outcome.append(0)
            stop.set()
            return
        printed += 1
        if opts.count and printed >= opts.count:
            stop.set()

    def on_signal(code: int) -> None:
        outcome.append(code)
        stop.set()

    endpoint.set_handler(on_message)
    endpoint.add_raw_route("/", on_raw)
    loop = asyncio.get_running_loop()
    loop.add_signal_handler(signal.SIGINT, on_signal, INTERRUPTED)
    loop.add_signal_handler(signal.SIGTERM, on_signal, 0)
    print(f"batteur echo: printing {subscribe.pattern} from {', '.join(t.address for t in reachable)} "
          "(Ctrl-C stops)", file=sys.stderr)
    deadline = None if opts.duration is None else loop.time() + opts.duration
    try:
        while not stop.is_set():
            for target in reachable:
                endpoint.send(subscribe, target.socket_address)
            wait = RENEW_S if deadline is None else min(RENEW_S, deadline - loop.time())
            if wait <= 0:
                break
            try:
                await asyncio.wait_for(stop.wait(), wait)
            except TimeoutError:
                pass
    finally:
        endpoint.close()
    if outcome:
        return outcome[0]
    return 0 if answered or printed else 1


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="batteur echo", description=DESCRIPTION,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("pattern", help="OSC address pattern, e.g. '/batteur/impact' or '/batteur/*' (quote it)")
    parser.add_argument("--node", action="append", default=[], metavar="HOST:PORT",
                        help="subscribe at this node instead of browsing (repeatable)")
    parser.add_argument("--interface", action="append", default=[], help=f"interface to browse on: {INTERFACE_HELP}")
    parser.add_argument("--browse", type=seconds, default=BROWSE_S, help=BROWSE_HELP)
    parser.add_argument("--count", type=count, default=0, help="stop after this many messages (default: no limit)")
    parser.add_argument("--duration", type=seconds, default=None,
                        help="stop after this many seconds (default: until Ctrl-C)")
    parser.add_argument("--json", action="store_true", help="one JSON object per line")
    parser.add_argument("--copies", action="store_true",
                        help="print every copy of a message sent redundantly (same seq), not only the first")
    opts = parser.parse_args(argv)

    def run() -> int:
        subscribe = check_pattern(opts.pattern)
        return asyncio.run(_run(opts, subscribe))

    return run_tool("batteur echo", run)
