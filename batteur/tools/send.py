"""``batteur send ADDRESS ARGS...``: send one OSC message, validated against its model.

Arguments are typed by the model registered at the address (so ``1`` becomes
an int or a float as the model says); an address without a model is sent as
given (numbers with a dot are floats, other numbers ints, the rest strings)
only with ``--raw``.
"""

from __future__ import annotations

import argparse
import asyncio
import difflib
import math
import re
import select
import socket
import struct
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass

from pythonosc.osc_message_builder import BuildError

from batteur.errors import USAGE, report_error
from batteur.tools.ls import match_answers, query_health
from batteur.tools.nodes import (
    BROWSE_HELP,
    BROWSE_S,
    INTERFACE_HELP,
    RIG_HELP,
    Target,
    browse_interfaces,
    browse_targets,
    chosen_rig,
    left_out_text,
    of_rig,
    resolve_host,
    run_tool,
    unique,
    where_browsed,
)
from common.arg_types import seconds, take_negative_values
from common.datafile import one_line
from common.messages import (
    REGISTRY,
    Arg,
    DropReason,
    Health,
    MessageError,
    OscMessage,
    WireKind,
    encode,
    encode_raw,
    parse_packet,
)
from common.transport import REFUSAL_ENDINGS, format_address, parse_address, taken_elsewhere

OSC_ADDRESS = re.compile(r"(?:/[!-.0-~]+)+")
"""An OSC address: '/'-separated parts of printable ASCII..."""
OSC_RESERVED = set(" #*,?[]{}")
"""...without the characters OSC reserves for patterns and type tags (a node could not match the message)."""
ROLE = re.compile(r"[a-z][a-z0-9_-]*")
EXAMPLE = "batteur send /batteur/graphics/latency 0.1 --to graphics"
EXAMPLE_ADDRESS = "/batteur/sound/master"
"""The help's examples: registered addresses (tests/test_send_help.py checks them)."""
PROG = "batteur send"
"""The command's name in its usage and error lines."""


def guess_arg(text: str) -> Arg:
    """An untyped command-line argument as int, float or string."""
    try:
        return int(text)
    except ValueError:
        pass
    try:
        return float(text)
    except ValueError:
        return text


def arguments(model: type[OscMessage]) -> str:
    """The arguments a message takes, as a usage line names them: ``ACTION TIME_WHOLE_S TIME_FRACTION POSITION``
    (a rig time is two on the wire), ``NAME...`` for a list at the end; `` (or TIME_S for TIME_WHOLE_S
    TIME_FRACTION)`` when a rig time may be given as one number of seconds (:func:`split_times`); ``, or ...``
    the model's shorter form (``OscMessage.SHORT_FORM``: the camera's preset alone)."""
    names: list[str] = []
    for f in model.wire_fields():
        name = f.name.upper()
        names += [f"{name}_WHOLE_S", f"{name}_FRACTION"] if f.kind is WireKind.TIME else [name]
        if f.variadic:
            names[-1] += "..."
    times = [f.name.upper() for f in model.wire_fields() if f.kind is WireKind.TIME]
    one = "" if not times or model.wire_fields()[-1].variadic else " (or " + ", ".join(
        f"{t}_S for {t}_WHOLE_S {t}_FRACTION" for t in times) + ")"
    short = f", or {model.SHORT_FORM}" if model.SHORT_FORM else ""
    return " ".join(names) + one + short


def split_times(model: type[OscMessage], texts: Sequence[str]) -> list[str] | None:
    """``texts`` with each rig time given as one number of seconds (``play 12.25 0``) split into the whole seconds
    and fraction the wire carries (``play 12 0.25 0``); None unless ``texts`` has one value per field, the last
    appended ones perhaps left out (:func:`one_number_form`; else they are taken as given, the wire's form). A
    time there that is not a finite number raises :class:`MessageError` naming the field (``TIME: must be a finite
    number of seconds``): the count is the one-number form's, so "expected 4 arguments" would be wrong."""
    fields = model.wire_fields()
    if not one_number_form(model, texts) or not any(f.kind is WireKind.TIME for f in fields):
        return None
    out: list[str] = []
    for f, text in zip(fields, texts, strict=False):  # appended fields left out stay out (their defaults)
        if f.kind is not WireKind.TIME:
            out.append(text)
            continue
        value = guess_arg(text)
        if isinstance(value, str) or not math.isfinite(value):
            raise MessageError(DropReason.OUT_OF_RANGE if not isinstance(value, str) else DropReason.WRONG_TYPE,
                               f"{f.name.upper()}: must be a finite number of seconds, got {text!r}", model.ADDRESS)
        whole = math.floor(value)
        out += [str(int(whole)), repr(float(value - whole))]
    return out


def one_number_form(model: type[OscMessage], texts: Sequence[str]) -> bool:
    """Whether ``texts`` may be the one-number-time form: one value per field, or without the last of the
    message's appended fields (``APPENDED``: an Impact's 11 values from before ``openness``, which until 8 Dec was
    the whole message), and not rather an older sender's wire form (:func:`older_wire_form`)."""
    fields = model.wire_fields()
    if not fields or fields[-1].variadic or not 0 <= len(fields) - len(texts) <= len(model.APPENDED):
        return False
    return not older_wire_form(model, texts)


def older_wire_form(model: type[OscMessage], texts: Sequence[str]) -> bool:
    """Whether ``texts``, one per field, are rather the wire form of a sender from before the message's last
    appended fields (``APPENDED``: each rig time as its whole seconds and fraction, the appended fields left out:
    a Contact's 17 arguments from before ``openness``), which has as many values: fewer of them of the wrong kind
    read that way than as :func:`split_times`' one-number form (until 7 Dec the old form was read as the new one,
    ``step: expected an integer, got 0.5``)."""
    fields = model.wire_fields()
    wire: list[WireKind] = []
    for f in fields:
        wire += [WireKind.INT, WireKind.FLOAT] if f.kind is WireKind.TIME else [f.kind]
    if not model.APPENDED or not 0 < len(wire) - len(texts) <= len(model.APPENDED):
        return False
    one = [WireKind.FLOAT if f.kind is WireKind.TIME else f.kind for f in fields]
    return _wrong_kinds(wire, texts) < _wrong_kinds(one, texts)


def _wrong_kinds(kinds: Sequence[WireKind], texts: Sequence[str]) -> int:
    """How many of ``texts`` would not be a value of their field's kind (``kinds``, in order)."""
    wrong = 0
    for kind, text in zip(kinds, texts, strict=False):
        value = guess_arg(text)
        if kind is WireKind.INT:
            wrong += not isinstance(value, int)
        elif kind is WireKind.FLOAT:
            wrong += isinstance(value, str)
        elif kind is WireKind.STR:
            wrong += not isinstance(value, str)
    return wrong


def relative_times(model: type[OscMessage] | None, texts: Sequence[str]) -> dict[int, float]:
    """The rig times written ``+SECONDS`` (``play +2 0``: two seconds after the node's rig time when send runs),
    by their index in ``texts``, as those seconds. Only where a time is one number (:func:`split_times`'s form).
    A ``+`` that is not a finite number of seconds, 0 or more, raises :class:`MessageError` naming the field."""
    if model is None:
        return {}
    fields = model.wire_fields()
    if not one_number_form(model, texts):
        return {}
    out: dict[int, float] = {}
    for i, (f, text) in enumerate(zip(fields, texts, strict=False)):
        if f.kind is not WireKind.TIME or not text.startswith("+"):
            continue
        value = guess_arg(text[1:])
        if isinstance(value, str) or not math.isfinite(value) or value < 0 or text[1:2] in "+-":
            raise MessageError(DropReason.WRONG_TYPE if isinstance(value, str) else DropReason.OUT_OF_RANGE,
                               f"{f.name.upper()}: +SECONDS must be a finite number of seconds, 0 or more, got "
                               f"{text!r}", model.ADDRESS)
        out[i] = float(value)
    return out


def at_rig_time(texts: Sequence[str], relative: dict[int, float], rig_time_s: float) -> list[str]:
    """``texts`` with each ``+SECONDS`` time (:func:`relative_times`) made the rig time ``rig_time_s`` + SECONDS."""
    return [repr(rig_time_s + relative[i]) if i in relative else t for i, t in enumerate(texts)]


@dataclass(frozen=True)
class RigTimeReading:
    """A node's rig time as its Health said it: ``rig_time_s`` (the Health's), the Hello's round trip
    (``round_trip_s``) and when the Health arrived (``arrived_s``, ``time.monotonic``)."""

    rig_time_s: float
    round_trip_s: float
    arrived_s: float

    def now(self, at_s: float) -> float:
        """The node's rig time at ``at_s`` (``time.monotonic``): the Health's, plus its way back (half the round
        trip, as a clock ping counts it) and the time since it arrived. Taken right before sending: a rig time read
        before a slow round trip (a loaded machine) made ``+0.5`` a note already late when it arrived."""
        return self.rig_time_s + self.round_trip_s / 2 + max(at_s - self.arrived_s, 0.0)


def rig_times(targets: Sequence[tuple[str, int]], timeout_s: float,
              strays: dict[str, Health] | None = None) -> dict[tuple[str, int], RigTimeReading]:
    """Each target's rig time, from the Health it answers to a Hello (``batteur ls``'s request) within
    ``timeout_s``; a target that does not answer (or whose host does not resolve) is left out. ``strays``: the
    Healths that came from other hosts, by source (not used: anyone may send one; said when a target is silent)."""
    asked: list[Target] = []
    for host, port in targets:
        try:
            asked.append(Target(host, port, ip=resolve_host(host)))
        except ValueError:
            asked.append(Target(host, port))  # no ip: not asked, so no answer
    timing: dict[str, tuple[float, float]] = {}
    answers = asyncio.run(query_health(asked, timeout_s, timing=timing, strays=strays))
    source = {id(h): s for s, h in answers.items()}
    out: dict[tuple[str, int], RigTimeReading] = {}
    for t, h in zip(asked, match_answers(asked, answers), strict=True):
        if h is not None:
            hello_s, arrived_s = timing[source[id(h)]]
            out[(t.host, t.port)] = RigTimeReading(h.time, max(arrived_s - hello_s, 0.0), arrived_s)
    return out


def stray_text(host: str, port: int, strays: dict[str, Health]) -> str:
    """Why a target's Health did not count: one came from another address (a node answering from another of its
    addresses: dropped, anyone may send one), or none came."""
    if not strays:
        return "its Health did not come: is a Batteur node running there?"
    came = ", ".join(f"{source} (node {h.node_id})" for source, h in sorted(strays.items()))
    return (f"a Health came from {came}, not from {format_address(host, port)}: a node answering from another of "
            "its addresses is not taken (anyone could send one)")


LATE = re.compile(r"at (?P<at>\d+(?:\.\d+)?) s arrived at (?P<arrived>\d+(?:\.\d+)?) s")
"""How physics says when a live note refused as late was for and when it came (its ``/batteur/physics/rejected``
reason: ``live note snare at 12.400 s arrived at 12.250 s: less than 300 ms to prepare it; not played``)."""
PREPARE = re.compile(r"less than (?P<ms>\d+(?:\.\d+)?) ms to prepare")
PAST = re.compile(r"at (?P<at>\d+(?:\.\d+)?) s is in the past \(now (?P<now>\d+(?:\.\d+)?) s\)")
"""How a node says a time it was sent is already past (``strike at 3.0000 s is in the past (now 3.2000 s)``)."""
OFFSET_STEP_S = 0.5
"""A larger +SECONDS suggested for a refused late message: the next multiple of this above what it lacked."""


def late_hint(reason: str, offset_s: float, resolved_s: float) -> str | None:
    """What to say of a refusal (its ``reason``) of a message sent with ``+offset_s`` (resolved to rig time
    ``resolved_s``) when the node refused it for being late: how late, and a larger offset to try; a late note
    that came with the lead the node needs is said refused for another timing reason (quoted), with no offset;
    None for any other refusal (a pitch of no drum: a larger offset would not help)."""
    late = LATE.search(reason)
    past = PAST.search(reason)
    prepare = PREPARE.search(reason)
    if late is not None and prepare is not None:
        lead = float(late["at"]) - float(late["arrived"])  # what it had left when it arrived
        need = float(prepare["ms"]) / 1000
        short = need - lead
        if short <= 0:  # it had the lead the node needs: refused for another timing reason, not a short offset
            return (f"{PROG}: +{offset_s:g} s was rig time {resolved_s:.3f} s and arrived {lead * 1000:.0f} ms "
                    f"before its time, at least the {need * 1000:.0f} ms the node needs to prepare it: the node "
                    f"refused it for another timing reason ({reason!r}); a larger offset may not help")
        how = (f"it arrived {lead * 1000:.0f} ms before its time, {short * 1000:.0f} ms short of the "
               f"{need * 1000:.0f} ms the node needs to prepare it")
    elif late is not None:  # late for another cause (the planner still loading): a larger offset would not help
        return None
    elif past is not None:
        short = float(past["now"]) - float(past["at"])
        how = f"it arrived {short * 1000:.0f} ms after its time"
    elif re.search(r"\blate\b|in the past|already past", reason):
        short, how = 0.0, "the node says it came too late"
    else:
        return None
    larger = math.floor((offset_s + short) / OFFSET_STEP_S + 1) * OFFSET_STEP_S
    return (f"{PROG}: +{offset_s:g} s was rig time {resolved_s:.3f} s and came too late: {how}; a larger offset "
            f"leaves more: try +{larger:g}")


def typed_args(address: str, texts: Sequence[str]) -> list[Arg]:
    """Command-line strings typed by the model at ``address``; raise MessageError on a mismatch."""
    model = REGISTRY.get(address)
    if model is None:
        return [guess_arg(t) for t in texts]
    texts = split_times(model, texts) or texts
    kinds: list[WireKind] = []
    for f in model.wire_fields():
        if f.kind is WireKind.TIME:
            kinds += [WireKind.INT, WireKind.FLOAT]
        else:
            kinds.append(f.kind)
    variadic = bool(model.wire_fields()) and model.wire_fields()[-1].variadic
    args: list[Arg] = []
    for i, text in enumerate(texts):
        kind = kinds[min(i, len(kinds) - 1)] if (i < len(kinds) or variadic) else WireKind.STR
        if kind is WireKind.STR:
            args.append(text)
        else:
            guessed = guess_arg(text)  # a string here lets the model report the wrong type
            if kind is WireKind.INT and isinstance(guessed, float) and guessed.is_integer():
                guessed = int(guessed)
            elif kind is WireKind.FLOAT and isinstance(guessed, int):
                guessed = float(guessed)
            args.append(guessed)
    return args


def wrong_role(model: type[OscMessage] | None, target: str) -> str | None:
    """Why ``--to ROLE`` would lose the control ``model`` (a service's node takes only its own service's controls,
    and drops the others, counted as ``wrong_node`` and answered with its refusal: a live note sent to interaction),
    or None: the nodes' own rule (:func:`common.transport.taken_elsewhere`). Refused here before any is sent; sent
    ``--to HOST:PORT`` of such a node, the node's refusal is what ``--replies`` shows."""
    owner = taken_elsewhere(model, target) if model is not None else ""
    if model is None or not owner:
        return None
    return f"--to {target}: {model.ADDRESS} is a control of {owner}; {target} nodes ignore it (--to {owner})"


SIMILAR = 0.8
"""How alike a registered address must be to be suggested for an unregistered one (difflib's ratio: 0.8 takes a
letter or two more, less or swapped in a /batteur/FAMILY/NAME address, and leaves /my/synth/freq without one). A
suggestion only: registered addresses can be as alike (/batteur/sound/model and /batteur/sound/modes)."""


def did_you_mean(address: str) -> str:
    """`` (did you mean /batteur/score/tempo?)`` for an address close to a registered one (``/batteur/score/tempoo``:
    a typo), else ""."""
    close = difflib.get_close_matches(address, sorted(m.ADDRESS for m in REGISTRY), n=1, cutoff=SIMILAR)
    return f" (did you mean {close[0]}?)" if close else ""


def check_raw_address(address: str) -> None:
    """ValueError unless ``address`` is one OSC address (not a pattern)."""
    bad = sorted(OSC_RESERVED.intersection(address))
    if not OSC_ADDRESS.fullmatch(address) or bad:
        why = f" (no {' '.join(repr(c) for c in bad)})" if bad else ""
        raise ValueError(f"{address!r} is not an OSC address: '/'-separated parts of printable ASCII{why}")


def _resolve(target: str, browse_s: float, interfaces: Sequence[str], rig: str) -> list[tuple[str, int]]:
    """``host:port`` as given, or the nodes of a role discovery finds within ``browse_s`` seconds (as ``batteur ls``
    and ``echo`` browse: :func:`~batteur.tools.nodes.browse_targets`) on ``interfaces`` (``--interface``; none:
    :func:`~batteur.tools.nodes.browse_interfaces`'s default), of rig ``rig`` (another class's drummer is not
    started); ValueError when ``target`` is neither."""
    if ":" in target or target.startswith("["):
        return [parse_address(target)]  # ValueError: a bad host form or a port outside 1-65535
    if not ROLE.fullmatch(target):
        raise ValueError(f"{target!r} is neither HOST:PORT nor a role (physics, sound, ...)")
    browse_on, source = browse_interfaces(interfaces)
    every, others = of_rig(asyncio.run(browse_targets(browse_s, browse_on)), rig)
    found = [(t.host, t.port) for t in unique([t for t in every if t.role == target]) if t.host]
    if not found:
        roles = ", ".join(sorted({t.role for t in every})) or "none"
        report_error(PROG, f"no {target} node found {where_browsed(browse_on, source)} within {browse_s:g} s "
                     f"(roles found: {roles}; --browse to look longer; HOST:PORT needs the port)"
                     + (f"; {left_out_text(others, rig)}" if others else ""))
    return found


def _encode(address: str, args: Sequence[Arg]) -> bytes:
    """The packet; MessageError when the model refuses it, ValueError when OSC cannot carry a value."""
    model = REGISTRY.get(address)
    try:
        return encode(model.from_args(args)) if model is not None else encode_raw(address, args)
    except (OverflowError, struct.error, BuildError) as exc:  # a float beyond 32 bits, an int beyond int32
        raise ValueError(f"{address}: a value does not fit its OSC type ({one_line(exc)})") from None


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog=PROG,
        description="Send one OSC message. Arguments are checked against the message model at ADDRESS "
        "(see docs/osc.md for every address and its arguments); a message that would be rejected is not sent. "
        "Exit status: 0 sent, 1 not sent (no node found, network error; with --replies also: refused, or "
        "nothing listening), 2 bad arguments.",
        epilog=f"example: {EXAMPLE}",
    )
    take_negative_values(parser)
    parser.add_argument("address", help=f"OSC address, e.g. {EXAMPLE_ADDRESS}")
    parser.add_argument("args", nargs="*", help="the message's arguments, in order (a rig time is one number of "
                        "seconds, or two as on the wire: whole seconds, then the fraction; +SECONDS is that long "
                        "after the node's rig time when send runs, asked of the node first: "
                        "/batteur/score/transport play +2 0 --to physics starts the score in 2 s)")
    parser.add_argument("--to", required=True,
                        help="HOST:PORT ([::1]:9000 for IPv6), or a role (physics, sound, ...) found by discovery: "
                        "every node of that role; a service's node takes only its own service's controls "
                        "(score messages go to physics), so another's is refused")
    parser.add_argument("--raw", action="store_true", help="allow an address without a model (sent as typed)")
    parser.add_argument("--replies", type=seconds, default=0.0, metavar="SECONDS",
                        help="then listen this long for answers and print them, one line each (a control's error, "
                        "a list...); exit 1 if a node refused the message or nothing listened; a node that stays "
                        "silent (an accepted control) is said on stderr (default 0: do not wait)")
    parser.add_argument("--browse", type=seconds, default=BROWSE_S, help=f"with --to ROLE: {BROWSE_HELP}")
    parser.add_argument("--timeout", type=seconds, default=2.0,
                        help="seconds to wait for a node's rig time (+SECONDS) (default 2)")
    parser.add_argument("--interface", action="append", default=[],
                        help=f"interface to look for a role on: {INTERFACE_HELP}")
    parser.add_argument("--rig", default=None, metavar="NAME", help=f"with --to ROLE: {RIG_HELP}")
    opts = parser.parse_args(argv)
    return run_tool(PROG, lambda: _send(opts))


def _send(opts: argparse.Namespace) -> int:
    model = REGISTRY.get(opts.address)
    if model is None and not opts.raw:
        return report_error(PROG, f"no message is registered at {opts.address}{did_you_mean(opts.address)} (see "
                            "docs/osc.md; --raw sends it anyway)", USAGE)
    try:
        if model is None:
            check_raw_address(opts.address)
        relative = relative_times(model, opts.args)
        # checked before any node is asked (the rig time 0 in place of +SECONDS: a time the model takes)
        data = _encode(opts.address, typed_args(opts.address, at_rig_time(opts.args, relative, 0.0)))
    except MessageError as exc:
        takes = f"; {opts.address} takes {arguments(model)}" if model and exc.reason is DropReason.WRONG_ARITY else ""
        return report_error(PROG, f"{exc}{takes}", USAGE)
    lost = wrong_role(model, opts.to)
    if lost is not None:
        return report_error(PROG, lost, USAGE)
    try:
        targets = _resolve(opts.to, opts.browse, opts.interface, chosen_rig(opts.rig))
    except ValueError as exc:
        return report_error(PROG, f"--to {one_line(exc)}", USAGE)
    if not targets:
        return 1
    failed = 0
    readings: dict[tuple[str, int], RigTimeReading] = {}
    if relative:
        strays: dict[str, Health] = {}
        readings = rig_times(targets, opts.timeout, strays)
        for host, port in targets:
            if (host, port) not in readings:
                failed += 1
                # a loaded machine answers late (a walkthrough's took over 2 s; --timeout 15 worked): name the flag
                report_error(PROG, f"no rig time from {format_address(host, port)} within --timeout "
                             f"{opts.timeout:g} s ({stray_text(host, port, strays)}); +SECONDS needs it, not sent "
                             "(a loaded machine may answer later: raise --timeout, e.g. --timeout 10)")
        targets = [t for t in targets if t in readings]
    sent: list[tuple[socket.socket, str]] = []  # kept open to hear the answers (--replies)
    hints: dict[str, tuple[float, float]] = {}  # target -> (+SECONDS, the rig time it was made): said if late
    try:
        for host, port in targets:
            family = socket.AF_INET6 if ":" in host else socket.AF_INET
            sock = socket.socket(family, socket.SOCK_DGRAM)
            try:  # connected, so the kernel reports a port nobody listens on (ICMP) to --replies
                sock.connect((host, port))
                if relative:  # +SECONDS made a rig time as late as can be: right before it is sent
                    now = readings[(host, port)].now(time.monotonic())
                    try:
                        data = _encode(opts.address, typed_args(opts.address, at_rig_time(opts.args, relative, now)))
                    except MessageError as exc:  # a time beyond what the wire carries, say
                        sock.close()
                        failed += 1
                        report_error(PROG, f"{format_address(host, port)}: {exc}")
                        continue
                    first = min(relative)
                    hints[format_address(host, port)] = (relative[first], now + relative[first])
                sock.send(data)
            except (OSError, UnicodeError) as exc:  # an unknown host name, an unreachable network: say so, go on
                sock.close()
                failed += 1
                report_error(PROG, f"cannot send to {format_address(host, port)}: "
                             f"{getattr(exc, 'strerror', None) or exc}")
                continue
            sent.append((sock, format_address(host, port)))
        if opts.replies > 0 and sent:
            failed += _print_replies(sent, opts.replies, hints)
    finally:
        for sock, _ in sent:
            sock.close()
    return 1 if failed else 0


REFUSALS = REFUSAL_ENDINGS
"""How the addresses of the answers that refuse a message end (``/batteur/interaction/error``,
``/batteur/sound/rejected``, ``/batteur/subscribe/refused``): the nodes' own list."""


def _print_replies(sent: Sequence[tuple[socket.socket, str]], wait_s: float,
                   hints: dict[str, tuple[float, float]] | None = None) -> int:
    """Print every answer the targets send back within ``wait_s`` seconds, one line each (``FROM ADDRESS ARGS``);
    returns how many targets refused the message (an answer at an address ending as :data:`REFUSALS`) or were
    not listening (the kernel's port-unreachable). ``hints``: target -> (+SECONDS, the rig time it was made) of a
    message sent with a relative time: a refusal of it for being late is followed by how late, and a larger
    offset to try (:func:`late_hint`, on standard error)."""
    deadline = time.monotonic() + wait_s
    names = {sock: name for sock, name in sent}
    refused: set[str] = set()
    answered: set[str] = set()
    while names and (left := deadline - time.monotonic()) > 0:
        ready, _, _ = select.select(list(names), [], [], left)
        for sock in ready:
            name = names[sock]
            try:
                data, _ = sock.recvfrom(65536)
            except ConnectionRefusedError:  # ICMP port unreachable for what was sent
                report_error(PROG, f"nothing listens at {name}")
                refused.add(name)
                del names[sock]
                continue
            except OSError as exc:
                print(f"batteur send: {name}: {exc.strerror or exc}", file=sys.stderr)
                del names[sock]
                continue
            answered.add(name)
            try:
                raws = parse_packet(data)
            except MessageError as exc:
                print(f"{name} (an answer that is not OSC: {exc})")
                continue
            for raw in raws:
                print(" ".join([name, raw.address, *(str(a) for a in raw.args)]), flush=True)
                if raw.address.endswith(REFUSALS):
                    refused.add(name)
                    hint = None if hints is None or name not in hints else late_hint(
                        " ".join(str(a) for a in raw.args), *hints[name])
                    if hint is not None:
                        print(hint, file=sys.stderr, flush=True)
    for name in sorted(set(names.values()) - answered):  # silence: not a failure, an accepted control gets none
        print(f"batteur send: no reply from {name} within {wait_s:g} s (a node answers a refusal or a request, "
              "not an accepted control; an address it does not know is dropped)", file=sys.stderr)
    return len(refused)
