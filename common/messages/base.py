"""Typed OSC messages: the pydantic base class and its flat wire form.

Every message Batteur sends is a subclass of :class:`OscMessage` with a class
variable ``ADDRESS`` and ordinary pydantic fields. On the wire a message is a
flat list of OSC ``i`` (int32), ``f`` (float32) and ``s`` (string) arguments in
field order, which Pure Data vanilla's ``[oscformat]``/``[oscparse]`` can build
and parse. Two field kinds have a special wire form:

* :data:`RigTime` (seconds on the rig clock) is sent as two arguments, whole
  seconds (``i``) and the fraction (``f``), because a float32 alone loses
  sample accuracy after a few minutes.
* a last field typed ``tuple[float, ...]`` (or int/str) is a variadic tail: its
  items follow the fixed arguments.

Decoding (:meth:`OscMessage.from_args`) checks arity and types itself, so every
failure carries one :class:`DropReason`; pydantic then checks ranges.
"""

from __future__ import annotations

import enum
import math
import types
import typing
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Annotated, Any, ClassVar, Self, Union, get_args, get_origin

from pydantic import BaseModel, ConfigDict, ValidationError, model_validator

from common.datafile import first_error

Arg = int | float | str
"""One OSC argument as Batteur sends it."""

INT32_MIN = -(2**31)
INT32_MAX = 2**31 - 1
FLOAT32_MAX = 3.4028234663852886e38
"""The largest number an OSC ``f`` argument (a 32-bit float) holds."""


class DropReason(enum.StrEnum):
    """Why an incoming packet or message was dropped. Counted per reason."""

    MALFORMED = "malformed"  # not a parseable OSC packet
    UNKNOWN_ADDRESS = "unknown_address"  # no model registered at that address
    WRONG_ARITY = "wrong_arity"  # too few or too many arguments
    WRONG_TYPE = "wrong_type"  # e.g. a string where a number is expected
    OUT_OF_RANGE = "out_of_range"  # value outside the field's declared range, NaN, inf
    OVERSIZE = "oversize"  # datagram larger than the configured limit
    NOT_ALLOWED = "not_allowed"  # sender outside the allow-list
    RATE_LIMITED = "rate_limited"  # sender over its message rate
    HANDLER_ERROR = "handler_error"  # the receiving handler raised
    WRONG_NODE = "wrong_node"  # a valid control of another service, sent to a node that does not take it


class Family(enum.StrEnum):
    """Message families of the design (ARCHITECTURE.md, Messages)."""

    CONTROL = "control"
    STATE = "state"
    CONTACTS = "contacts"
    IMPACTS = "impacts"
    HEALTH = "health"
    CLOCK = "clock"


class MessageError(ValueError):
    """A message that cannot be decoded, with the reason it is dropped."""

    def __init__(self, reason: DropReason, detail: str, address: str = "") -> None:
        super().__init__(f"{reason.value}: {address + ': ' if address else ''}{detail}")
        self.reason = reason
        self.detail = detail
        self.address = address


class _RigTimeMarker:
    """Marks a float field as a rig-clock time (seconds), sent as ``i`` + ``f``."""


RigTime = Annotated[float, _RigTimeMarker()]
"""Seconds on the rig clock; on the wire: whole seconds (i) then fraction (f)."""


class WireKind(enum.StrEnum):
    INT = "i"
    FLOAT = "f"
    STR = "s"
    TIME = "t"  # two args: i then f


@dataclass(frozen=True)
class WireField:
    """How one model field appears on the wire."""

    name: str
    kind: WireKind
    variadic: bool
    description: str
    minimum: float | None
    maximum: float | None
    choices: tuple[str, ...] | None
    exclusive_minimum: bool = False
    """True when ``minimum`` itself is refused (pydantic ``gt``), False when it is taken (``ge``)."""
    exclusive_maximum: bool = False
    """True when ``maximum`` itself is refused (``lt``), False when it is taken (``le``)."""


def _scalar_kind(annotation: Any) -> WireKind:
    if annotation is int:
        return WireKind.INT
    if annotation is float:
        return WireKind.FLOAT
    if annotation is str:
        return WireKind.STR
    origin = get_origin(annotation)
    if origin is typing.Literal:
        values = get_args(annotation)
        if all(isinstance(v, str) for v in values):
            return WireKind.STR
        if all(isinstance(v, int) for v in values):
            return WireKind.INT
    if isinstance(annotation, type) and issubclass(annotation, enum.StrEnum):
        return WireKind.STR
    if isinstance(annotation, type) and issubclass(annotation, enum.IntEnum):
        return WireKind.INT
    if origin is Annotated:
        return _scalar_kind(get_args(annotation)[0])
    raise TypeError(f"field type {annotation!r} cannot go on the OSC wire (use int, float, str)")


def _choices(annotation: Any) -> tuple[str, ...] | None:
    if get_origin(annotation) is typing.Literal:
        return tuple(str(v) for v in get_args(annotation))
    if isinstance(annotation, type) and issubclass(annotation, enum.Enum):
        return tuple(str(m.value) for m in annotation)
    return None


def _bounds(metadata: list[Any]) -> tuple[float | None, float | None, bool, bool]:
    """(minimum, maximum, minimum exclusive, maximum exclusive) of a field's ``ge``/``gt``/``le``/``lt``."""
    low: float | None = None
    high: float | None = None
    low_exclusive = high_exclusive = False
    for item in metadata:
        for attr in ("ge", "gt"):
            value = getattr(item, attr, None)
            if value is not None:
                low, low_exclusive = float(value), attr == "gt"
        for attr in ("le", "lt"):
            value = getattr(item, attr, None)
            if value is not None:
                high, high_exclusive = float(value), attr == "lt"
    return low, high, low_exclusive, high_exclusive


class OscMessage(BaseModel):
    """Base of every Batteur OSC message.

    Subclasses set ``ADDRESS`` (the OSC address), ``FAMILY`` and a docstring
    (used in docs/osc.md and OSCQuery descriptions). Field descriptions should
    state units (seconds, metres, newtons, Hz).
    """

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    ADDRESS: ClassVar[str] = ""
    FAMILY: ClassVar[Family] = Family.CONTROL
    SHORT_FORM: ClassVar[str] = ""
    """Another argument list :meth:`from_args` takes besides every field in order, as a usage line says it
    (``batteur send``'s; ``PRESET alone ...``); "" for none."""
    APPENDED: ClassVar[tuple[str, ...]] = ()
    """Fields appended to the message since it was first sent, oldest first (each with a default): a sender from
    before them (an older node, a Pd patch) sends the arguments without the last of them, which :meth:`from_args`
    decodes with their defaults."""
    NEWER_ARGS: ClassVar[int] = 0
    """Arguments after the last known field a newer sender's message may carry (fields appended since this node):
    :meth:`from_args` ignores up to this many (each message with ``APPENDED`` fields sets its own: 8, Health 16)."""

    @classmethod
    def wire_fields(cls) -> tuple[WireField, ...]:
        """The fields in wire order, with kinds, ranges and descriptions."""
        cached = cls.__dict__.get("_wire_fields_cached")
        if cached is not None:
            return typing.cast(tuple[WireField, ...], cached)
        hints = typing.get_type_hints(cls, include_extras=True)
        fields: list[WireField] = []
        names = list(cls.model_fields)
        for index, name in enumerate(names):
            info = cls.model_fields[name]
            annotation = hints[name]
            variadic = False
            kind: WireKind
            base = get_args(annotation)[0] if get_origin(annotation) is Annotated else annotation
            extras = get_args(annotation)[1:] if get_origin(annotation) is Annotated else ()
            origin = get_origin(base)
            if any(isinstance(e, _RigTimeMarker) for e in extras):
                kind = WireKind.TIME
            elif origin in (tuple, list):
                args = get_args(base)
                if index != len(names) - 1:
                    raise TypeError(f"{cls.__name__}.{name}: only the last field may be variadic")
                variadic = True
                kind = _scalar_kind(args[0])
            elif origin in (Union, types.UnionType):
                raise TypeError(f"{cls.__name__}.{name}: optional or union fields cannot go on the wire")
            else:
                kind = _scalar_kind(base)
            low, high, low_exclusive, high_exclusive = _bounds(list(info.metadata))
            fields.append(
                WireField(
                    name=name,
                    kind=kind,
                    variadic=variadic,
                    description=info.description or "",
                    minimum=low,
                    maximum=high,
                    choices=_choices(base),
                    exclusive_minimum=low_exclusive,
                    exclusive_maximum=high_exclusive,
                )
            )
        result = tuple(fields)
        type.__setattr__(cls, "_wire_fields_cached", result)
        return result

    @classmethod
    def _unbounded_floats(cls) -> tuple[tuple[str, bool], ...]:
        """(name, variadic) of the float fields whose declared range lets a value beyond a 32-bit float in."""
        cached = cls.__dict__.get("_unbounded_floats_cached")
        if cached is None:
            try:
                fields = cls.wire_fields()
            except TypeError:  # a message with its own wire layout (interaction's registered ones): nothing to check
                fields = ()
            cached = tuple((f.name, f.variadic) for f in fields if f.kind is WireKind.FLOAT and not (
                f.minimum is not None and f.maximum is not None and max(-f.minimum, f.maximum) <= FLOAT32_MAX))
            type.__setattr__(cls, "_unbounded_floats_cached", cached)
        return typing.cast(tuple[tuple[str, bool], ...], cached)

    @model_validator(mode="after")
    def _fits_the_wire(self) -> Self:
        """Refuse a float OSC cannot carry (beyond 32 bits) when the message is made, not when it is sent."""
        for name, variadic in self._unbounded_floats():
            value = getattr(self, name)
            if (max(map(abs, value), default=0.0) if variadic else abs(value)) > FLOAT32_MAX:
                raise ValueError(f"{name}: beyond a 32-bit float (OSC 'f' holds at most {FLOAT32_MAX:.4g})")
        return self

    @classmethod
    def type_tags(cls) -> str:
        """OSC type tags of the fixed part (``t`` expands to ``if``; a variadic tail ends in ``*``)."""
        tags = ""
        for f in cls.wire_fields():
            tags += "if" if f.kind is WireKind.TIME else f.kind.value
            if f.variadic:
                tags += "*"
        return tags

    def to_args(self) -> list[Arg]:
        """The flat OSC argument list, in field order."""
        out: list[Arg] = []
        for f in self.wire_fields():
            value = getattr(self, f.name)
            if f.variadic:
                if f.kind is WireKind.FLOAT:  # validated floats already (a pose's hundreds of values)
                    out.extend(value)
                else:
                    out.extend(_plain(v) for v in value)
            elif f.kind is WireKind.TIME:
                whole = math.floor(value)
                out.append(int(whole))
                out.append(float(value - whole))
            else:
                out.append(_plain(value))
        return out

    @classmethod
    def from_args(cls, args: Sequence[Any]) -> Self:
        """Build a message from decoded OSC arguments; raise :class:`MessageError`.

        Accepts floats with integral values for int fields (Pure Data sends
        every number as a float) and ints for float fields.
        """
        fields = cls.wire_fields()
        fixed = [f for f in fields if not f.variadic]
        fixed_count = sum(2 if f.kind is WireKind.TIME else 1 for f in fixed)
        has_tail = bool(fields) and fields[-1].variadic
        if not has_tail and (cls.APPENDED or cls.NEWER_ARGS):  # an older or a newer sender's (see APPENDED)
            missing = fixed_count - len(args)
            if 0 < missing <= len(cls.APPENDED):
                args = [*args, *(cls.model_fields[name].default for name in cls.APPENDED[-missing:])]
            elif 0 < -missing <= cls.NEWER_ARGS:
                args = args[:fixed_count]
        if len(args) < fixed_count or (not has_tail and len(args) != fixed_count):
            want = f"{fixed_count}{'+' if has_tail else ''}"
            raise MessageError(
                DropReason.WRONG_ARITY, f"expected {want} arguments, got {len(args)}", cls.ADDRESS
            )
        values: dict[str, Any] = {}
        pos = 0
        for f in fixed:
            if f.kind is WireKind.TIME:
                whole = _coerce(args[pos], WireKind.INT, f.name, cls.ADDRESS)
                frac = _coerce(args[pos + 1], WireKind.FLOAT, f.name, cls.ADDRESS)
                if not 0.0 <= float(frac) <= 1.0:  # 1.0: float32 rounding of 0.99999999
                    raise MessageError(DropReason.OUT_OF_RANGE, f"{f.name}: fraction {frac} is not in [0, 1)",
                                       cls.ADDRESS)
                if float(whole) + float(frac) >= INT32_MAX:
                    raise MessageError(DropReason.OUT_OF_RANGE, f"{f.name}: {whole} s does not fit", cls.ADDRESS)
                values[f.name] = float(whole) + float(frac)
                pos += 2
            else:
                values[f.name] = _coerce(args[pos], f.kind, f.name, cls.ADDRESS)
                pos += 1
        if has_tail:
            tail = fields[-1]
            rest = args[pos:]
            # a tail of finite floats (a pose) is taken whole; anything else is checked value by value
            if tail.kind is WireKind.FLOAT and set(map(type, rest)) <= {float} and math.isfinite(sum(rest)):
                values[tail.name] = tuple(rest)
            else:
                values[tail.name] = tuple(_coerce(a, tail.kind, tail.name, cls.ADDRESS) for a in rest)
        for f in fixed:
            if f.kind is WireKind.FLOAT:
                values[f.name] = _snap_to_bounds(values[f.name], f)
        try:
            return cls.model_validate(values)
        except ValidationError as exc:
            raise MessageError(DropReason.OUT_OF_RANGE, first_error(exc), cls.ADDRESS) from None


FLOAT32_EPS = 2.0**-23


def _snap_to_bounds(value: float, f: WireField) -> float:
    """Undo float32 rounding at a range bound: 0.01 sent as float32 arrives as 0.0099999998.

    Only values within float32 rounding of a bound are moved onto it; anything
    further out stays out of range and is rejected.
    """
    for bound in (f.minimum, f.maximum):
        if bound is not None and value != bound and abs(value - bound) <= FLOAT32_EPS * max(abs(bound), 1e-30):
            return bound
    return value


def _plain(value: Any) -> Arg:
    if isinstance(value, enum.Enum):
        return typing.cast(Arg, value.value)
    if isinstance(value, bool):
        return int(value)
    return typing.cast(Arg, value)


def _coerce(value: Any, kind: WireKind, name: str, address: str) -> Arg:
    if kind is WireKind.STR:
        if isinstance(value, str):
            return value
        raise MessageError(DropReason.WRONG_TYPE, f"{name}: expected a string, got {value!r}", address)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise MessageError(DropReason.WRONG_TYPE, f"{name}: expected a number, got {value!r}", address)
    if isinstance(value, float) and not math.isfinite(value):
        raise MessageError(DropReason.OUT_OF_RANGE, f"{name}: {value} is not finite", address)
    if kind is WireKind.INT:
        if isinstance(value, float):
            if not value.is_integer():
                raise MessageError(DropReason.WRONG_TYPE, f"{name}: expected an integer, got {value}", address)
            value = int(value)
        if not INT32_MIN <= value <= INT32_MAX:
            raise MessageError(DropReason.OUT_OF_RANGE, f"{name}: {value} does not fit int32", address)
        return value
    return float(value)
