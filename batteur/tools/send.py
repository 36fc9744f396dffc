"""``batteur send ADDRESS ARGS...``: send one OSC message, validated against its model.

Arguments are typed by the model registered at the address (so ``1`` becomes
an int or a float as the model says); an address without a model is sent as
given (numbers with a dot are floats, other numbers ints, the rest strings)
only with ``--raw``.
"""

from __future__ import annotations

import argparse
import asyncio
import socket
import sys
from collections.abc import Sequence

from common.arg_types import seconds
from common.messages import REGISTRY, Arg, MessageError, WireKind, encode, encode_raw
from common.transport import parse_address


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


def typed_args(address: str, texts: Sequence[str]) -> list[Arg]:
    """Command-line strings typed by the model at ``address``; raise MessageError on a mismatch."""
    model = REGISTRY.get(address)
    if model is None:
        return [guess_arg(t) for t in texts]
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


def _resolve(target: str, timeout_s: float) -> list[tuple[str, int]]:
    """``host:port`` as given, or the discovered nodes of a role."""
    host, sep, port = target.rpartition(":")
    if sep and port.isdigit():
        return [parse_address(target)]  # ValueError: a bad host form or a port outside 1-65535
    from common.discovery import browse_nodes  # only when a role must be found

    nodes = asyncio.run(browse_nodes(timeout_s, None))
    return [(n.host, n.port) for n in nodes if n.role == target]


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="batteur send",
        description="Send one OSC message. Arguments are checked against the message model at ADDRESS "
        "(see docs/osc.md); a message that would be rejected is not sent.",
    )
    parser.add_argument("address", help="OSC address, e.g. /batteur/sound/param")
    parser.add_argument("args", nargs="*", help="the message's arguments, in order")
    parser.add_argument("--to", required=True, help="HOST:PORT, or a role (physics, sound, ...) found by discovery")
    parser.add_argument("--raw", action="store_true", help="allow an address without a model (sent as typed)")
    parser.add_argument("--timeout", type=seconds, default=2.0, help="seconds to look for a role (default 2)")
    opts = parser.parse_args(argv)

    model = REGISTRY.get(opts.address)
    if model is None and not opts.raw:
        print(f"batteur send: no message is registered at {opts.address} (use --raw to send it anyway)",
              file=sys.stderr)
        return 2
    try:
        args = typed_args(opts.address, opts.args)
        data = encode(model.from_args(args)) if model is not None else encode_raw(opts.address, args)
    except MessageError as exc:
        print(f"batteur send: {exc}", file=sys.stderr)
        return 2
    try:
        targets = _resolve(opts.to, opts.timeout)
    except ValueError as exc:
        print(f"batteur send: --to {exc}", file=sys.stderr)
        return 2
    if not targets:
        print(f"batteur send: no node found for {opts.to!r}", file=sys.stderr)
        return 1
    failed = 0
    for host, port in targets:
        family = socket.AF_INET6 if ":" in host else socket.AF_INET
        try:
            with socket.socket(family, socket.SOCK_DGRAM) as sock:
                sock.sendto(data, (host, port))
        except OSError as exc:  # an unknown host name, an unreachable network: say so, try the other nodes
            failed += 1
            print(f"batteur send: cannot send to {host}:{port}: {exc}", file=sys.stderr)
    return 1 if failed else 0
