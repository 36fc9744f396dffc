"""``batteur echo PATTERN``: print the messages whose address matches an OSC pattern.

Each node found (zeroconf, or ``--node HOST:PORT``) is sent a ``Subscribe``
and copies every matching message it sends or receives to this tool, which
renews the subscription while it runs. A node that refuses it (table full, bad
pattern) answers ``SubscribeRefused``: echo says so once per node. Each node
is asked for its Health every second (:class:`Presence`): echo says when one
goes away and when it comes back. Stops on Ctrl-C, after ``--count`` messages
or after ``--duration`` seconds.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
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
    RIG_HELP,
    OutputClosed,
    Target,
    bind_address,
    browse_interfaces,
    chosen_rig,
    find_targets,
    left_out_text,
    of_rig,
    run_tool,
    target_networks,
    where_browsed,
    write_line,
)
from common.arg_types import count, seconds
from common.messages import (
    PROTOCOL_VERSION,
    ClockStatus,
    Health,
    Hello,
    Impact,
    OscMessage,
    RawMessage,
    Subscribe,
    SubscribeRefused,
)
from common.messages.interaction import Damping, ImpactEnd
from common.messages.system import TOOL_ROLE
from common.subscribe import matches, pattern_regex
from common.transport import UdpEndpoint

RENEW_S = 5.0
REDUNDANT = (Impact, ImpactEnd, Damping)
"""What interaction sends several times with one ``seq`` (its redundancy): the copies of one are one message. A
clock ping or pong's ``seq`` is its asker's: two nodes' pongs of one number are two messages."""
PROBE_S = 2.0
"""How long to wait for each node's Health before saying it does not answer."""
HEARTBEAT_S = 1.0
"""How often echo asks each node for its Health while it runs (a Hello, as ``batteur ls``): a node that stopped
was followed in silence, as if it had nothing to say."""
GONE_AFTER = 3
"""Heartbeats a node may leave unanswered (sending nothing else either) before echo says it went away."""

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
reason. Each node is asked for its Health every second: one that stops answering for 3 s
(stopped, or out of reach) is said on standard error, and so is its return (echo keeps asking,
and subscribes again at once); echo's own Hellos and each node's answers to them (Health,
clock status, physics' skeleton) are not printed; the same answered to another (batteur ls) are.

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


async def _probe(targets: Sequence[Target]) -> tuple[list[Target], dict[str, str]]:
    """The targets that answer a Hello, and the node ids they answer with by address; say which do not (echo
    would otherwise wait in silence)."""
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
    return answered, {t.socket_address: answers[t.socket_address].node_id for t in answered}


class Presence:
    """Which nodes answer: echo asks each for its Health every :data:`HEARTBEAT_S` (a Hello from an endpoint of its
    own), hears anything a node sends it, and says when a node that answered stops (nothing for
    :data:`GONE_AFTER` heartbeats: it stopped, or the network between went down) and when one comes back, or
    answers for the first time; echo keeps subscribing to it meanwhile (the node forgets a subscription when it
    stops: one that comes back is subscribed again at once).

    A node copies what it receives and sends, so our Hello and its answers to it (Health, ClockStatus, physics'
    Skeleton) come back as copies when the pattern matches them (``/batteur/*``): they are not the rig's messages and
    are not printed (:meth:`ours`). A copy says neither where it went nor where it came from (the node's packet as
    sent), and a ClockStatus or a Skeleton is the same bytes whoever it answers: each answer on the heartbeat
    endpoint stands for exactly one copy from its node with its content, the next one (the node sends the answer,
    then its copy). A user's ``batteur ls`` answered the same a second later is its own copy, printed."""

    def __init__(self, targets: Sequence[Target], answered: Sequence[Target], now: float,
                 hello: Hello) -> None:
        self.targets = {t.socket_address: t for t in targets if t.ip}
        self.heard = {t.socket_address: now for t in answered if t.ip}
        """Node address -> when it was last heard (``loop.time()``); a node never heard is not in it."""
        self.gone: set[str] = set()
        self.names: dict[str, str] = {t.socket_address: t.node_id for t in targets if t.ip and t.node_id}
        self.hello_key = _key(hello)
        self.expected: dict[tuple[str, tuple[object, ...]], list[float]] = {}
        """(node address, content) of each answer to our Hellos whose copy has not come -> until when each is
        awaited (``loop.time()``): a copy the pattern does not match never comes."""

    def where(self, address: str) -> str:
        target = self.targets[address]
        name = self.names.get(address)
        return f"node {name} at {target.address}" if name else f"the node at {target.address}"

    def answer(self, message: OscMessage, source: str, now: float) -> str | None:
        """A message on the heartbeat endpoint (the answers to our Hellos); what to say, if anything."""
        self.expected.setdefault((source, _key(message)), []).append(now + HEARTBEAT_S)
        if isinstance(message, Health):
            if source not in self.targets:  # a node answering from another of its addresses: known by its id
                source = next((a for a, name in self.names.items() if name == message.node_id), source)
            else:
                self.names[source] = message.node_id
        return self.heard_from(source, now)

    def heard_from(self, source: str, now: float) -> str | None:
        """Anything from node address ``source``; says when a node gone (or never heard) answers."""
        if source not in self.targets:
            return None
        first = source not in self.heard
        self.heard[source] = now
        if first:
            return f"batteur echo: {self.where(source)} answers now; subscribed"
        if source in self.gone:
            self.gone.discard(source)
            return f"batteur echo: {self.where(source)} is back; subscribed again"
        return None

    def went_away(self, now: float) -> list[str]:
        """The nodes newly silent for :data:`GONE_AFTER` heartbeats, one line each."""
        lines = []
        for address, last in self.heard.items():
            if address not in self.gone and now - last > GONE_AFTER * HEARTBEAT_S:
                self.gone.add(address)
                lines.append(f"batteur echo: {self.where(address)} went away (no answer for "
                             f"{now - last:.0f} s: stopped, or out of reach); still asking for it every "
                             f"{HEARTBEAT_S:g} s: its messages are printed again if it comes back")
        for key, untils in list(self.expected.items()):
            untils[:] = [u for u in untils if u >= now]
            if not untils:
                del self.expected[key]
        return lines

    def ours(self, message: OscMessage, source: str, now: float) -> bool:
        """Whether ``message``, copied by the node at ``source``, is its copy of our Hello or of one of its answers to
        our Hellos (each answer matches one copy: taken here)."""
        key = _key(message)
        if key == self.hello_key:  # our node id and port: no one else's Hello
            return True
        untils = self.expected.get((source, key))
        while untils and untils[0] < now:  # its copy never came (a pattern that does not match it, a lost datagram)
            untils.pop(0)
        if not untils:
            return False
        untils.pop(0)
        return True


def _key(message: OscMessage) -> tuple[object, ...]:
    return (message.ADDRESS, *message.to_args())


async def _run(opts: argparse.Namespace, subscribe: Subscribe) -> int:
    interfaces, source = browse_interfaces(opts.interface)
    rig = chosen_rig(opts.rig)
    targets, others = of_rig(await find_targets(opts.node, opts.browse, interfaces), rig)
    if others:  # on stderr: another class's nodes on the network, said so a missing node is not a mystery
        print(f"batteur echo: {left_out_text(others, rig)}", file=sys.stderr, flush=True)
    if not targets:
        return report_error("batteur echo", f"no nodes found {where_browsed(interfaces, source)} within "
                            f"{opts.browse:g} s (start one, or give --node HOST:PORT)")
    answered, names = await _probe(targets)
    reachable = [t for t in targets if t.ip]
    if not reachable:
        return 1
    endpoint = await UdpEndpoint.open(bind_address(reachable), allow=target_networks(reachable))
    heartbeat = await UdpEndpoint.open(bind_address(reachable), allow=target_networks(reachable))
    loop = asyncio.get_running_loop()
    stop = asyncio.Event()
    printed = 0
    outcome: list[int] = []  # set by what stopped us: Ctrl-C, or the reader of our output going away
    refusals = Refusals(subscribe.pattern, reachable)
    first_copies = FirstCopies()
    hello = Hello(role=TOOL_ROLE, node_id=f"batteur-echo-{os.getpid()}", protocol=PROTOCOL_VERSION,
                  osc_port=heartbeat.port)
    presence = Presence(reachable, answered, loop.time(), hello)
    presence.names.update(names)

    def say(line: str | None, source: str) -> None:
        if line is None:
            return
        print(line, file=sys.stderr, flush=True)
        if source in presence.targets and not stop.is_set():  # back: subscribed again at once, not at the renewal
            endpoint.send(subscribe, source)

    def on_answer(message: OscMessage, source: str) -> None:
        say(presence.answer(message, source, loop.time()), source)

    def on_message(message: OscMessage, source: str) -> None:
        say(presence.heard_from(source, loop.time()), source)
        refused = refusals.line(message, source)
        if refused is not None:
            print(refused, file=sys.stderr)
        if stop.is_set() or not matches(opts.pattern, message.ADDRESS):
            return
        # the node sent its answer before its copy: already waiting on the heartbeat socket when the copy is read, but
        # asyncio may call this socket's reader first. Read it now (no wait, so nothing is delayed or reordered)
        heartbeat._drain()
        if not presence.ours(message, source, loop.time()):
            print_message(message)

    def print_message(message: OscMessage) -> None:
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
    heartbeat.set_handler(on_answer)
    loop.add_signal_handler(signal.SIGINT, on_signal, INTERRUPTED)
    loop.add_signal_handler(signal.SIGTERM, on_signal, 0)
    print(f"batteur echo: printing {subscribe.pattern} from {', '.join(t.address for t in reachable)} "
          "(Ctrl-C stops)", file=sys.stderr)
    deadline = None if opts.duration is None else loop.time() + opts.duration
    renew_at = loop.time()
    try:
        while not stop.is_set():
            now = loop.time()
            if now >= renew_at:
                for target in reachable:
                    endpoint.send(subscribe, target.socket_address)
                renew_at = now + RENEW_S
            for line in presence.went_away(now):
                print(line, file=sys.stderr, flush=True)
            for target in reachable:  # a node that stopped (or never answered) is asked still
                heartbeat.send(hello, target.socket_address)
            wait = HEARTBEAT_S if deadline is None else min(HEARTBEAT_S, deadline - loop.time())
            if wait <= 0:
                break
            try:
                await asyncio.wait_for(stop.wait(), wait)
            except TimeoutError:
                pass
    finally:
        stop.set()
        endpoint.close()
        heartbeat.close()
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
    parser.add_argument("--rig", default=None, metavar="NAME", help=RIG_HELP)
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
