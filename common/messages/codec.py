"""Encode typed messages to OSC packets and decode packets back, with python-osc.

python-osc builds and parses the bytes; this module adds the registry lookup,
validation and one :class:`~common.messages.base.DropReason` per failure.
Bundles are accepted (nested too); their timetags are ignored, because timed
messages carry their time as an explicit argument (ARCHITECTURE.md, Messages).

Batteur's own messages (one message of ``i``, ``f`` and ``s`` arguments) take
a fast path: one ``struct`` call packs or unpacks all the arguments, the same
bytes and values python-osc gives (tested). python-osc builds a message by
appending argument by argument to a byte string and then parses it back, and
parses a float per function call: a pose of 280 floats cost about 0.3 ms each
way, a fifth of an offline render. A message's variadic float tail (a
pose's values) is also typed and checked as one run, not value by value (the
drummer's pose of 700 floats: 89 -> 38 us to encode, 141 -> 52 us to decode
with its validation). Anything else (bundles, other argument types, a packet
that is not canonical, every error) goes through python-osc.
"""

from __future__ import annotations

import struct
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

from pythonosc.osc_bundle_builder import IMMEDIATELY, OscBundleBuilder
from pythonosc.osc_message import OscMessage as PyOscMessage
from pythonosc.osc_message_builder import OscMessageBuilder
from pythonosc.osc_packet import OscPacket, ParseError

from common.messages.base import Arg, DropReason, MessageError, OscMessage
from common.messages.registry import REGISTRY, MessageRegistry


def _build(address: str, args: Sequence[Arg]) -> PyOscMessage:
    builder = OscMessageBuilder(address=address)
    for arg in args:
        if isinstance(arg, bool):
            builder.add_arg(int(arg), OscMessageBuilder.ARG_TYPE_INT)
        elif isinstance(arg, int):
            builder.add_arg(arg, OscMessageBuilder.ARG_TYPE_INT)
        elif isinstance(arg, float):
            builder.add_arg(arg, OscMessageBuilder.ARG_TYPE_FLOAT)
        elif isinstance(arg, str):
            builder.add_arg(arg, OscMessageBuilder.ARG_TYPE_STRING)
        else:
            raise TypeError(f"{address}: argument {arg!r} is not int, float or str")
    return builder.build()


def _osc_string(text: str) -> bytes:
    """An OSC string: UTF-8, a null, padded with nulls to a multiple of 4 bytes (python-osc's ``write_string``)."""
    raw = text.encode("utf-8")
    return raw + b"\0" * (4 - len(raw) % 4)


def _pack(address: str, args: Sequence[Arg], floats_from: int | None = None) -> bytes:
    """The fast path of :func:`encode_raw`: every argument in one ``struct.pack``. ``floats_from``: where a tail
    of floats may start (a pose's values), packed as one run when it holds floats only."""
    tags: list[str] = []
    fmt: list[str] = [">"]
    values: list[object] = []
    tail: Sequence[Arg] = ()
    if floats_from is not None and set(map(type, args[floats_from:])) <= {float}:
        args, tail = args[:floats_from], args[floats_from:]
    for arg in args:
        kind = type(arg)
        if kind is float:
            tags.append("f")
            fmt.append("f")
            values.append(arg)
        elif kind is int or kind is bool:
            tags.append("i")
            fmt.append("i")
            values.append(int(arg))
        elif kind is str:
            raw = _osc_string(arg)  # type: ignore[arg-type]
            tags.append("s")
            fmt.append(f"{len(raw)}s")
            values.append(raw)
        else:
            raise TypeError(f"{address}: argument {arg!r} is not int, float or str")
    if tail:
        tags.append("f" * len(tail))
        fmt.append(f"{len(tail)}f")
        values.extend(tail)
    return _osc_string(address) + _osc_string("," + "".join(tags)) + struct.pack("".join(fmt), *values)


def encode_raw(address: str, args: Sequence[Arg], floats_from: int | None = None) -> bytes:
    """One OSC message from an address and plain arguments (ints as i, floats as f). ``floats_from``: where
    a tail of floats may start (only speed depends on it)."""
    if address:
        try:
            return _pack(address, args, floats_from)
        except (struct.error, OverflowError, UnicodeError):
            pass  # out of range or not encodable: python-osc says why
    return bytes(_build(address, args).dgram)


def encode(message: OscMessage) -> bytes:
    """The OSC packet for one typed message."""
    args = message.to_args()
    tail = None
    if type(message).to_args is OscMessage.to_args:  # the wire layout is the fields' (not a custom to_args)
        fields = message.wire_fields()
        if fields and fields[-1].variadic:
            tail = len(args) - len(getattr(message, fields[-1].name))
    return encode_raw(message.ADDRESS, args, tail)


def encode_bundle(messages: Iterable[OscMessage], timetag: float | None = None) -> bytes:
    """Several messages in one OSC bundle (timetag: Unix time in seconds, or immediately)."""
    builder = OscBundleBuilder(IMMEDIATELY if timetag is None else timetag)  # type: ignore[arg-type]
    for message in messages:
        builder.add_content(_build(message.ADDRESS, message.to_args()))  # type: ignore[arg-type]
    return bytes(builder.build().dgram)


@dataclass
class RawMessage:
    """A parsed OSC message before it is matched to a model."""

    address: str
    args: list[Arg]


@dataclass
class Decoded:
    """What one datagram held: valid typed messages and the errors of the rest."""

    messages: list[OscMessage] = field(default_factory=list)
    errors: list[MessageError] = field(default_factory=list)


def _padded(end: int) -> int:
    """Index after an OSC string whose terminating null is at ``end``."""
    return end + 4 - end % 4


def _unpack(data: bytes) -> RawMessage | None:
    """The fast path of :func:`parse_packet`: a canonical message of ``i``, ``f`` and ``s`` arguments in as few
    ``struct`` calls as it has strings; None for anything else (python-osc parses it, or says what is wrong)."""
    if not data.startswith(b"/"):
        return None
    try:
        end = data.index(0)
        address = data[:end].decode("utf-8")
        index = _padded(end)
        end = data.index(0, index)
        tags = data[index:end].decode("ascii")
        index = _padded(end)
        if not tags.startswith(","):
            return None
        args: list[Arg] = []
        run = ""
        for tag in tags[1:] + "|":
            if tag in "if":
                run += tag
                continue
            if run:
                args.extend(struct.unpack_from(">" + run, data, index))
                index += 4 * len(run)
                run = ""
            if tag == "s":
                end = data.index(0, index)
                args.append(data[index:end].decode("utf-8"))
                index = _padded(end)
            elif tag != "|":
                return None
    except (ValueError, struct.error):
        return None
    return RawMessage(address=address, args=args) if index == len(data) else None


def parse_packet(data: bytes) -> list[RawMessage]:
    """Parse an OSC packet (message or bundle) into raw messages; raise MessageError if malformed."""
    fast = _unpack(data)
    if fast is not None:
        return [fast]
    try:
        packet = OscPacket(data)
    except ParseError as exc:
        raise MessageError(DropReason.MALFORMED, str(exc) or "unparseable OSC packet") from None
    except Exception as exc:  # python-osc raises assorted errors on truncated data
        raise MessageError(DropReason.MALFORMED, f"{type(exc).__name__}: {exc}") from None
    out: list[RawMessage] = []
    for timed in packet.messages:
        msg = timed.message
        args: list[Arg] = []
        for p in msg.params:
            if isinstance(p, (bool, int, float, str)):
                args.append(int(p) if isinstance(p, bool) else p)
            else:  # blobs, MIDI, nil...: the model check reports a wrong type
                args.append(_Unsupported(p))  # type: ignore[arg-type]
        out.append(RawMessage(address=msg.address, args=args))
    return out


class _Unsupported:
    """An OSC argument of a type Batteur never uses (blob, MIDI, nil, ...)."""

    def __init__(self, value: object) -> None:
        self.value = value

    def __repr__(self) -> str:
        return f"<unsupported OSC argument {self.value!r}>"


def to_model(raw: RawMessage, registry: MessageRegistry = REGISTRY) -> OscMessage:
    """Validate a raw message against the model registered at its address."""
    model = registry.get(raw.address)
    if model is None:
        raise MessageError(DropReason.UNKNOWN_ADDRESS, "no message is registered here", raw.address)
    return model.from_args(raw.args)


def decode(data: bytes, registry: MessageRegistry = REGISTRY) -> Decoded:
    """Decode one datagram. Never raises: failures are returned per message."""
    result = Decoded()
    try:
        raws = parse_packet(data)
    except MessageError as exc:
        result.errors.append(exc)
        return result
    for raw in raws:
        try:
            result.messages.append(to_model(raw, registry))
        except MessageError as exc:
            result.errors.append(exc)
    return result
