"""``batteur ls``: list the nodes of a rig with their health.

Nodes are found by zeroconf (or given with ``--node HOST:PORT``); each is sent
a Hello and answers with its Health, then (nodes since 7 Dec) its ClockStatus.
Exit code 0 when every listed node answered, 1 otherwise (so
``batteur ls --node 127.0.0.1:9103`` is a healthcheck).
"""

from __future__ import annotations

import argparse
import asyncio
import ipaddress
import json
import math
import sys
import time
from collections.abc import Sequence
from contextlib import suppress

from batteur.errors import report_error
from batteur.tools.nodes import (
    BROWSE_HELP,
    BROWSE_S,
    INTERFACE_HELP,
    RIG_HELP,
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
from common.arg_types import seconds, take_negative_values
from common.messages import PROTOCOL_VERSION, ClockStatus, Health, Hello, OscMessage
from common.messages.system import TOOL_ROLE
from common.transport import UdpEndpoint, parse_address

DESCRIPTION = """\
List the Batteur nodes found by zeroconf (or given with --node), each with the Health it
answers to a Hello: role, node id, address, status, loop rate against its target, late events,
skipped steps (physics), dropped messages, errors (failures inside the service, such as a drum
whose strikes fail: its log has the first with its traceback), peers, and how its clock follows
the rig clock (the clock master's, physics' unless --clock-master says otherwise), from the
ClockStatus it sends after its Health (column clock).

Column status:
  ok
      the node answered, its loop keeping at least half its target rate
  behind
      it answered, but its loop ran under half its target rate over the last second (column
      rate/target Hz, e.g. 5.5/1000): the node skips steps to keep up with the rig clock, its
      service falls behind it (physics: column skipped counts the simulation steps it skipped,
      its log's "behind real time" warnings say the bar it was playing; the drummer plays late,
      by --json's target_lag; notes it then cannot play in time are its late events, column
      late, which skipped steps alone do not grow). A loop a little under its target is a busy
      machine's usual (sound at 186.7/187.5) and stays ok; a rate of 0 is not judged: the node
      has not stepped yet (its first second, or its core waiting for its clock master); "-" as
      the target: an event-driven node
  no answer, no address
      no Health came back; the node announced no usable address
Column skipped:
  physics' simulation steps skipped to follow the rig clock since it started (1 ms each at
  1 kHz; --json's skipped_steps): growing, it fell behind; 0 for the other services
Column clock:
  master
      this node's clock is the rig clock
  synced +/- 0.05 ms, rtt 0.12 ms
      following it: the half-width of the interval its offset lies in and the best ping
      round trip (", 2 steps": rig time stepped since it synced: the master restarted, or
      its clock moved)
  not synced (no pong from ID)
      the master ID (its node id, static:ROLE:HOST:PORT for a --peer) has not answered its
      pings yet; "not synced (no clock master found)": it knows of none
  ?
      no ClockStatus came (a node from before 7 Dec answers with its Health only)
--json gives the ClockStatus's fields as clock_status (null for "?"). --json adds
the rest of the Health: the drops by reason (dropped_malformed, dropped_unknown, dropped_type,
dropped_range, dropped_other, dropped_wrong_node: a control of another service sent to this
node, a note sent to interaction), unroutable (messages the node could not send: to a role no node
of which it knows, say sound when no sound node runs), duplicates (redundant copies of impacts
the sound node dropped: same sender, seq and time) and rig_time_s, the node's rig time when
it answered (seconds: what a timed message such as /batteur/impact is stamped with).

Browses on --interface, else on the interfaces in BATTEUR_INTERFACES (where the nodes of a
compose container announce: `docker compose exec graphics batteur ls` lists the rig), else on
loopback.

Exit status: 0 when every node listed answered (behind too: it runs), 1 when one did not (or
none was found), 2 on bad arguments; so `batteur ls --node 127.0.0.1:9103` is a healthcheck."""


BEHIND_FRACTION = 0.5
"""A node whose loop ran under this fraction of its target rate over the last Health interval is ``behind``. Under
its target at all, a loop has skipped deadlines (docs/runtime.md, "Fixed-rate loop": it never quietly runs slower),
but a few percent is a busy machine's usual (sound at 186.7 Hz of 187.5 on a rig that kept time); under half, it
misses more steps than it takes: a walkthrough's physics at 5.5 Hz of 1000 had counted 16513 late events; one at
13.5 Hz logged 136 steps behind the rig clock, its drummer playing 86 ms late. Health's docs give no threshold:
half is this tool's."""
ANSWERED = ("ok", "behind")
"""The statuses of a node that answered (exit status 0)."""


def status_of(health: Health) -> str:
    """``behind`` when the node's loop rate is under :data:`BEHIND_FRACTION` of its target (a rate of 0: not stepped
    yet, not judged; a target of 0: event-driven, no loop), else ``ok``."""
    target, rate = health.target_rate_hz, health.rate_hz
    return "behind" if target > 0 and 0 < rate < BEHIND_FRACTION * target else "ok"


def rate_text(row: dict[str, object]) -> str:
    """The ``rate/target Hz`` column: ``5.5/1000``; ``0.0/-`` for an event-driven node (target 0); "" without a
    Health."""
    if "rate_hz" not in row:
        return ""
    target = row.get("target_rate_hz")
    return f"{row['rate_hz']}/{f'{target:g}' if isinstance(target, float | int) and target > 0 else '-'}"


CLOCK_GRACE_S = 0.25
"""How long ls waits, once every node has answered with its Health, for the ClockStatus each sends right after it
(seconds): a node from before 7 Dec sends none ("?") and must not cost the whole ``--timeout``."""


async def query_health(targets: Sequence[Target], timeout_s: float,
                       clocks: dict[str, ClockStatus] | None = None,
                       timing: dict[str, tuple[float, float]] | None = None,
                       strays: dict[str, Health] | None = None) -> dict[str, Health]:
    """Send a Hello to each reachable target; collect the Health answers by source address within
    ``timeout_s`` (only the targets may answer). ``clocks``: also collect into it, by node id, the ClockStatus
    each node sends after its Health (waiting at most :data:`CLOCK_GRACE_S` more for them once every Health
    is in). ``timing``: also collect into it, by source address, when the Hello left and its Health arrived
    (``time.monotonic``, s): how old the Health's rig time is when it is used (``batteur send``'s +SECONDS).
    ``strays``: also collect into it, by source address, the Healths from hosts no target has (a node answering
    from another of its addresses): not answers (anyone may send one), but what a caller can name when its target
    seems silent."""
    reachable = [t for t in targets if t.ip]
    answers: dict[str, Health] = {}
    if not reachable:
        return answers
    allow = target_networks(reachable)
    allowed = [ipaddress.ip_network(n) for n in allow]
    # strays wanted: every source is read, and the targets' answers told from the others here
    endpoint = await UdpEndpoint.open(bind_address(reachable), allow=None if strays is not None else allow)
    healths_in = asyncio.Event()
    all_in = asyncio.Event()
    sent: dict[str, float] = {}  # source address -> when its Hello left (time.monotonic)

    def on_message(message: OscMessage, source: str) -> None:
        if strays is not None and not _from(source, allowed):
            if isinstance(message, Health):
                strays[source] = message
            return
        if isinstance(message, Health):
            answers[source] = message
            if timing is not None:  # a node answering from another address: its round trip from the first Hello
                timing[source] = (sent.get(source, min(sent.values(), default=time.monotonic())), time.monotonic())
        elif isinstance(message, ClockStatus) and clocks is not None:
            clocks[message.node_id] = message
        else:
            return
        if len(answers) >= len(reachable):
            healths_in.set()
            if clocks is None or all(h.node_id in clocks for h in answers.values()):
                all_in.set()

    endpoint.set_handler(on_message)
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout_s
    try:
        hello = Hello(role=TOOL_ROLE, node_id="batteur-ls", protocol=PROTOCOL_VERSION, osc_port=endpoint.port)
        for target in reachable:
            sent[target.socket_address] = time.monotonic()
            endpoint.send(hello, target.socket_address)
        with suppress(TimeoutError):
            await asyncio.wait_for(healths_in.wait(), timeout_s)
        if healths_in.is_set():
            with suppress(TimeoutError):
                await asyncio.wait_for(all_in.wait(), max(0.0, min(CLOCK_GRACE_S, deadline - loop.time())))
    finally:
        endpoint.close()
    return answers


def _from(source: str, networks: Sequence[ipaddress.IPv4Network | ipaddress.IPv6Network]) -> bool:
    """Whether ``source`` (``host:port``) is in one of ``networks`` (the endpoint's allow-list, checked by hand)."""
    try:
        ip = ipaddress.ip_address(parse_address(source)[0].split("%", 1)[0])
    except ValueError:
        return False
    return any(ip in net for net in networks)


def _ms(seconds: float) -> str:
    return f"{seconds * 1e3:.2f} ms"


def clock_text(status: ClockStatus | None) -> str:
    """How a node's clock follows the rig clock, in a few words (the ``clock`` column)."""
    if status is None:
        return "?"  # a node from before 7 Dec, or its ClockStatus lost
    if status.master == status.node_id:
        return "master"
    if not status.synced:
        if not status.master:
            return "not synced (no clock master found)"
        refused = f", {status.rejected} pongs refused" if status.rejected else ""
        return f"not synced (no pong from {status.master}{refused})"
    steps = f", {status.steps} step{'s' if status.steps != 1 else ''}" if status.steps else ""
    if status.uncertainty_s < 0 or not math.isfinite(status.uncertainty_s):  # a new master: estimating again
        return f"synced, no estimate yet from {status.master or 'a new master'}{steps}"
    return f"synced +/- {_ms(status.uncertainty_s)}, rtt {_ms(status.round_trip_s)}{steps}"


def match_answers(targets: Sequence[Target], answers: dict[str, Health]) -> list[Health | None]:
    """The Health each target answered: the one from its own address, else one carrying its node id (a
    node answering from another of its addresses). Never another node's answer on the same port."""
    left = dict(answers)
    matched: list[Health | None] = [left.pop(t.socket_address, None) if t.ip else None for t in targets]
    for i, target in enumerate(targets):
        if matched[i] is None and target.ip and target.node_id:
            source = next((s for s, h in left.items() if h.node_id == target.node_id), None)
            if source is not None:
                matched[i] = left.pop(source)
    return matched


def _row(target: Target, health: Health | None, clock: ClockStatus | None = None) -> dict[str, object]:
    row: dict[str, object] = {"role": target.role, "rig": target.rig or None, "node_id": target.node_id,
                              "address": target.address}  # rig None: a node given as HOST:PORT (not announced)
    if not target.ip:
        row["status"] = "no address"
        row["announced"] = list(target.announced)
        return row
    if health is None:
        row["status"] = "no answer"
        return row
    row.update(
        role=health.role, node_id=health.node_id, status=status_of(health), protocol=health.protocol,
        rig_time_s=round(health.time, 3),  # when it answered: a timed message (an impact, a score's start) needs it
        rate_hz=round(health.rate_hz, 1), target_rate_hz=health.target_rate_hz, overruns=health.overruns,
        messages_in=health.messages_in, messages_out=health.messages_out, dropped=health.dropped,
        dropped_malformed=health.dropped_malformed, dropped_unknown=health.dropped_unknown,
        dropped_type=health.dropped_type, dropped_range=health.dropped_range, dropped_other=health.dropped_other,
        late=health.late, peers=health.peers, decode_unanswered=health.decode_unanswered,
        replies_unanswered=health.replies_unanswered, target_lag=round(health.target_lag, 4),
        target_jumps=health.target_jumps, unroutable=health.unroutable, dropped_wrong_node=health.dropped_wrong_node,
        errors=health.errors, duplicates=health.duplicates, wrong_node_unanswered=health.wrong_node_unanswered,
        skipped_steps=health.skipped_steps, clock=clock_text(clock),
        discovery=("off", "on", "starting", "failed to start")[health.discovery],  # an older node's: "off"
        clock_status=clock.model_dump(mode="json") if clock is not None else None,
    )
    return row


def table(rows: Sequence[dict[str, object]]) -> list[str]:
    """The rows as aligned text lines, a header first."""
    lines = [f"{'role':<12} {'rig':<10} {'node id':<28} {'address':<22} {'status':<10} {'rate/target Hz':>14} "
             f"{'late':>6} {'skipped':>8} {'dropped':>8} {'errors':>6} {'peers':>5} clock"]
    for r in rows:
        lines.append(f"{r['role']!s:<12} {r.get('rig') or '?'!s:<10} {r['node_id']!s:<28} {r['address']!s:<22} "
                     f"{r['status']!s:<10} {rate_text(r):>14} {r.get('late', '')!s:>6} "
                     f"{r.get('skipped_steps', '')!s:>8} {r.get('dropped', '')!s:>8} "
                     f"{r.get('errors', '')!s:>6} {r.get('peers', '')!s:>5} {r.get('clock', '')!s}".rstrip())
    return lines


def looked_where(interfaces: Sequence[str], source: str, browse_s: float) -> str:
    """Where ``batteur ls`` browsed (the interfaces and their addresses) and how to look elsewhere: said with every
    list, not only an empty one (a teacher's ls on loopback listed the local nodes and silently left out the sound
    laptop). ``source``: where the interfaces came from (``--interface``, BATTEUR_INTERFACES; "": loopback)."""
    from common.discovery import resolve_interfaces

    try:
        addresses = resolve_interfaces(list(interfaces) or None)
    except Exception:  # noqa: BLE001 - an unknown name: the browse itself said so; the names are still worth saying
        addresses = []
    if not interfaces:
        return (f"batteur ls: browsed on loopback only ({', '.join(addresses) or '127.0.0.1'}) for {browse_s:g} s: "
                "nodes of other machines are not listed; to list them, browse on their network's interface: "
                "--interface eth0 (a name or an address, repeatable; 'all': every interface) or BATTEUR_INTERFACES")
    named = ", ".join(interfaces)
    shown = f" ({', '.join(addresses)})" if addresses and addresses != list(interfaces) else ""
    return (f"batteur ls: browsed on {named}{shown} ({source}) for {browse_s:g} s; to look elsewhere: "
            "--interface NAME (a name or an address, repeatable; 'all': every interface)")


async def _run(opts: argparse.Namespace) -> int:
    interfaces, source = browse_interfaces(opts.interface)
    rig = chosen_rig(opts.rig)
    targets, others = of_rig(await find_targets(opts.node, opts.browse, interfaces), rig)
    if others:  # on stderr: another class's nodes on the network, said so a missing node is not a mystery
        print(f"batteur ls: {left_out_text(others, rig)}", file=sys.stderr, flush=True)
    if not targets:
        return report_error("batteur ls", f"no nodes found {where_browsed(interfaces, source)} within "
                            f"{opts.browse:g} s (start one, or give --node HOST:PORT)")
    clocks: dict[str, ClockStatus] = {}
    answers = await query_health(targets, opts.timeout, clocks)
    rows = [_row(t, h, clocks.get(h.node_id) if h is not None else None)
            for t, h in zip(targets, match_answers(targets, answers), strict=True)]
    for line in [json.dumps(rows, indent=2)] if opts.json else table(rows):
        write_line(line)
    if not opts.node:  # on stderr, under the list: the table (or --json) stays what a script reads
        print(looked_where(interfaces, source, opts.browse), file=sys.stderr, flush=True)
    return 0 if all(r["status"] in ANSWERED for r in rows) else 1


def main(argv: Sequence[str] | None = None) -> int:
    parser = take_negative_values(argparse.ArgumentParser(prog="batteur ls", description=DESCRIPTION,
                                                          formatter_class=argparse.RawDescriptionHelpFormatter))
    parser.add_argument("--node", action="append", default=[], metavar="HOST:PORT",
                        help="ask this node instead of browsing (repeatable)")
    parser.add_argument("--interface", action="append", default=[], help=f"interface to browse on: {INTERFACE_HELP}")
    parser.add_argument("--rig", default=None, metavar="NAME", help=RIG_HELP)
    parser.add_argument("--browse", type=seconds, default=BROWSE_S, help=BROWSE_HELP)
    parser.add_argument("--timeout", type=seconds, default=2.0, help="seconds to wait for health answers (default 2)")
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    opts = parser.parse_args(argv)
    return run_tool("batteur ls", lambda: asyncio.run(_run(opts)))
