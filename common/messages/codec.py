"""Encode typed messages to OSC packets (with python-osc) and decode packets back.

python-osc builds the bytes; parsing is this module's own, because python-osc
1.10.2's parser hangs on a bundle element of negative size, reads ``T``/``F``
as numbers, skips type tags it does not know (and the arguments after them
then misalign) and logs each bad element to the root logger, unrated. This
module also does the registry lookup, validation and one
:class:`~common.messages.base.DropReason` per failure. Bundles are accepted
(nested up to :data:`MAX_BUNDLE_DEPTH`, checked whole by :func:`walk_packet`
before any message is parsed); their timetags are ignored, because timed
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
that is not canonical, every error) goes through :func:`_parse_message`.
"""

from __future__ import annotations

import struct
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

from pythonosc.osc_bundle_builder import IMMEDIATELY, OscBundleBuilder
from pythonosc.osc_message import OscMessage as PyOscMessage
from pythonosc.osc_message_builder import OscMessageBuilder

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
    ``struct`` calls as it has strings; None for anything else (:func:`_parse_message` parses it, or says what is
    wrong)."""
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
        for tag in tags[1:] + "\0":  # a sentinel no tag can be (the tags end at their null) flushes the last run
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
            elif tag != "\0":
                return None
    except (ValueError, struct.error):
        return None
    return RawMessage(address=address, args=args) if index == len(data) else None


BUNDLE_HEADER = b"#bundle\0"
"""How an OSC bundle starts; its 8-byte timetag follows."""
MAX_BUNDLE_DEPTH = 8
"""Bundles nested deeper than this are refused (``malformed``): Batteur sends one level; a few more are tolerated."""
NUMBER_TAGS = frozenset("ifhd")
"""OSC type tags taken as numbers: ``i``, ``f``, and ``h`` (int64) and ``d`` (float64), which some senders use for
the same numbers (an ``h`` must still fit its field's int32; a ``d``, a float32)."""


def walk_packet(data: bytes) -> tuple[list[tuple[int, int]], str]:
    """Where the messages of a packet are, from the bundle element sizes alone: (start, end) of each, in order,
    and "" or why the bundle structure is malformed (the messages found before the fault are still listed,
    for the rate limit's count). A packet that is no bundle is one message, checked when parsed.

    Every element size must be positive, a multiple of 4 and within its bundle; an element must be a message
    (``/...``) or a bundle, nested at most :data:`MAX_BUNDLE_DEPTH` deep. A bundle without elements is valid
    OSC ("zero or more elements"): it holds no message. Walked without recursion, every step moving forward,
    so any input ends (python-osc 1.10.2 looped forever on a negative size)."""
    if not data.startswith(BUNDLE_HEADER):
        return [(0, len(data))], ""
    if len(data) < 16:
        return [], f"bundle of {len(data)} bytes: shorter than its header and timetag (16 bytes)"
    spans: list[tuple[int, int]] = []
    stack = [(16, len(data))]  # (next element, end) of each bundle being walked, innermost last
    while stack:
        pos, end = stack[-1]
        if pos == end:
            stack.pop()
            continue
        if end - pos < 4:
            return spans, f"{end - pos} stray bytes at the end of a bundle (byte {pos})"
        (size,) = struct.unpack_from(">i", data, pos)
        pos += 4
        if size <= 0 or size % 4:
            return spans, f"bundle element size {size} at byte {pos - 4}: not a positive multiple of 4"
        if size > end - pos:
            return spans, f"bundle element of {size} bytes at byte {pos - 4}: only {end - pos} follow in its bundle"
        stack[-1] = (pos + size, end)
        if data.startswith(BUNDLE_HEADER, pos, pos + size):
            if size < 16:
                return spans, f"nested bundle of {size} bytes at byte {pos}: shorter than its header and timetag"
            if len(stack) >= MAX_BUNDLE_DEPTH:
                return spans, f"bundles nested deeper than {MAX_BUNDLE_DEPTH}"
            stack.append((pos + 16, pos + size))
        elif data.startswith(b"/", pos, pos + size):
            spans.append((pos, pos + size))
        else:
            return spans, f"bundle element at byte {pos} is neither a message nor a bundle: {data[pos:pos + 8]!r}"
    return spans, ""


def parse_packet(data: bytes) -> list[RawMessage]:
    """Parse an OSC packet (message or bundle) into raw messages; raise MessageError if malformed (the whole
    packet: a bundle whose structure or any message is malformed holds nothing to trust)."""
    fast = _unpack(data)
    if fast is not None:
        return [fast]
    spans, fault = walk_packet(data)
    if fault:
        raise MessageError(DropReason.MALFORMED, fault)
    if spans == [(0, len(data))]:
        return [_parse_message(data)]
    out: list[RawMessage] = []
    for start, end in spans:
        element = data[start:end]
        out.append(_unpack(element) or _parse_message(element))
    return out


_FIXED_SIZE = {"i": 4, "f": 4, "h": 8, "d": 8, "t": 8, "r": 4, "m": 4, "c": 4}
"""Bytes of each fixed-size OSC argument type."""
_NO_DATA_TAGS = frozenset("TFNI")
"""True, False, Nil, Impulse: a type tag without argument bytes."""


def _string_at(data: bytes, index: int, what: str) -> tuple[str, int]:
    """The OSC string at ``index`` and the index after its padding; MessageError if unterminated or cut short."""
    end = data.find(0, index)
    if end < 0:
        raise MessageError(DropReason.MALFORMED, f"{what} at byte {index} has no terminating null")
    after = _padded(end)
    if after > len(data):
        raise MessageError(DropReason.MALFORMED, f"{what} at byte {index} is cut short (no padding to 4 bytes)")
    try:
        return data[index:end].decode("utf-8"), after
    except UnicodeDecodeError:
        raise MessageError(DropReason.MALFORMED, f"{what} at byte {index} is not UTF-8") from None


def _parse_message(data: bytes) -> RawMessage:
    """One OSC message, any type tags (Batteur's own parser: python-osc skipped tags it did not know, logging
    each to the root logger, and read ``T``/``F`` as numbers). Numbers (:data:`NUMBER_TAGS`) and strings are
    arguments; every other argument is parsed past and kept as :class:`_Unsupported`, which the model refuses
    as a wrong type (or arity). A tag of unknown size, or bytes left after the last argument, is malformed."""
    if not data.startswith(b"/"):
        shown = data[:16]
        raise MessageError(DropReason.MALFORMED, f"not an OSC message or bundle: starts with {shown!r}"
                           if data else "empty packet")
    address, index = _string_at(data, 0, "address")
    if index == len(data):  # no type tag string: no arguments (OSC 1.0 lets old senders omit it)
        return RawMessage(address=address, args=[])
    tags, index = _string_at(data, index, "type tag string")
    if not tags.startswith(","):
        raise MessageError(DropReason.MALFORMED, f"type tag string {tags[:32]!r} does not start with ','", address)
    args: list[Arg] = []
    depth = 0  # inside an OSC array ([...]): its items are parsed past, the array is one unsupported argument
    for tag in tags[1:]:
        value: object
        if tag in _FIXED_SIZE:
            size = _FIXED_SIZE[tag]
            if index + size > len(data):
                if tag != "f" or index >= len(data):
                    raise MessageError(DropReason.MALFORMED, f"argument '{tag}' at byte {index} is cut short", address)
                # some senders (Reaktor) drop a last float's trailing nulls: read as padded, as python-osc does
                value = struct.unpack(">f", data[index:].ljust(4, b"\0"))[0]
            elif tag == "i":
                value = struct.unpack_from(">i", data, index)[0]
            elif tag == "f":
                value = struct.unpack_from(">f", data, index)[0]
            elif tag == "h":
                value = struct.unpack_from(">q", data, index)[0]
            elif tag == "d":
                value = struct.unpack_from(">d", data, index)[0]
            else:
                value = _Unsupported(tag, data[index:index + size])
            index += size
        elif tag in "sS":
            text, index = _string_at(data, index, f"argument '{tag}'")
            value = text if tag == "s" else _Unsupported(tag, text)
        elif tag == "b":
            if index + 4 > len(data):
                raise MessageError(DropReason.MALFORMED, f"blob size at byte {index} is cut short", address)
            (size,) = struct.unpack_from(">i", data, index)
            after = index + 4 + size + (-size % 4)
            if size < 0 or after > len(data):
                raise MessageError(DropReason.MALFORMED, f"blob of {size} bytes at byte {index}: "
                                   f"{len(data) - index - 4} follow", address)
            value = _Unsupported(tag, data[index + 4:index + 4 + size])
            index = after
        elif tag in _NO_DATA_TAGS:
            value = _Unsupported(tag, {"T": True, "F": False, "N": None, "I": "impulse"}[tag])
        elif tag == "[":
            if depth == 0:
                args.append(_Unsupported("[", "array"))  # type: ignore[arg-type]
            depth += 1
            continue
        elif tag == "]":
            if depth == 0:
                raise MessageError(DropReason.MALFORMED, f"']' without '[' in type tags {tags[:32]!r}", address)
            depth -= 1
            continue
        else:
            raise MessageError(DropReason.MALFORMED, f"unknown OSC type tag {tag!r}: its size is unknown", address)
        if depth == 0:
            args.append(value)  # type: ignore[arg-type]
    if depth:
        raise MessageError(DropReason.MALFORMED, f"'[' without ']' in type tags {tags[:32]!r}", address)
    if index < len(data):
        raise MessageError(DropReason.MALFORMED, f"{len(data) - index} bytes after the last argument "
                           f"(type tags {tags[:32]!r})", address)
    return RawMessage(address=address, args=args)


class _Unsupported:
    """An OSC argument of a type Batteur does not take (``T``, ``F``, ``N``, ``I``, blob, timetag, MIDI, ...):
    the model check reports it as a wrong type, naming the tag."""

    def __init__(self, tag: str, value: object) -> None:
        self.tag = tag
        self.value = value

    def __repr__(self) -> str:
        return f"OSC type '{self.tag}' ({self.value!r}; arguments are i, f or s)"


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
