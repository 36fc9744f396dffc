"""Mappings as data: impact features through curves into any message field or argument.

A :class:`Curve` turns one number into another: ``linear``, ``exp`` (an
exponential warp between two ranges) or ``table`` (piecewise linear through
points). An :class:`ArgSpec` is a feature (optionally through a curve) or a
constant, and has a one-string form used over OSC and in listings::

    velocity                        the feature as is
    velocity:linear:0:10:0:127@i    0..10 m/s -> 0..127, sent as an OSC int
    velocity:exp:0:10:0:1:4         exponential warp, curvature 4
    r:table:0:1:0.8:0.5:1:0         a table through (0, 1), (0.8, 0.5), (1, 0)
    =42   =0.5   =snare             constants

A :class:`Route` says where impacts go and which of the Impact's fields are
replaced by mapped values (the default, no field maps, is the one-to-one
physical mapping). A :class:`RegisteredMessage` is an extra message, any
address and arguments, sent to a role or host:port on every matching impact.

Everything must be sendable: numbers finite and within an OSC float32 (or
int32), ``host:port`` targets valid; a configuration holds at most
``MAX_ROUTES`` routes and ``MAX_MESSAGES`` registered messages of at most
``MAX_ARGS`` arguments.
"""

from __future__ import annotations

import math
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from common.datafile import one_line
from common.messages.base import INT32_MAX, INT32_MIN
from common.transport import parse_address
from services.interaction.detect import FEATURES, FLOAT32_MAX, STRING_FEATURES, ImpactFeatures

MAX_ROUTES = 32
"""Most routes a configuration holds: every impact goes out once per route and copy."""

MAX_MESSAGES = 64
"""Most registered messages a configuration holds (the file is written back on every edit)."""

MAX_ARGS = 32
"""Most arguments of one registered message."""


class MappingError(ValueError):
    """A mapping or spec that cannot be built or applied."""


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


def _sendable(value: float, what: str) -> float:
    """``value`` if an OSC float32 can carry it; ValueError otherwise (python-osc cannot pack it)."""
    if abs(value) > FLOAT32_MAX:
        raise ValueError(f"{what} {value:g} is beyond the largest OSC float ({FLOAT32_MAX:.4g})")
    return value


def _check_target(to: str) -> str:
    """A role name, or a HOST:PORT that can be sent to (ValueError with the reason)."""
    if to == "reply":  # the runtime's word for "the sender of the message being handled": physics, for an impact
        raise ValueError("'reply' is not a target (it would answer the physics node): give the client's host:port")
    if ":" in to or to.startswith("["):
        parse_address(to)
    return to


class LinearCurve(_Model):
    """y = out_min + (x - in_min) / (in_max - in_min) * (out_max - out_min), clipped to the ranges."""

    kind: Literal["linear"] = "linear"
    in_range: tuple[float, float] = (0.0, 1.0)
    out_range: tuple[float, float] = (0.0, 1.0)

    @field_validator("in_range")
    @classmethod
    def _distinct(cls, value: tuple[float, float]) -> tuple[float, float]:
        if value[0] == value[1]:
            raise ValueError("in_range needs two different values")
        return value

    @field_validator("out_range")
    @classmethod
    def _out_sendable(cls, value: tuple[float, float]) -> tuple[float, float]:
        for v in value:
            _sendable(v, "out_range value")
        return value

    def unit(self, x: float) -> float:
        lo, hi = self.in_range
        return min(max((x - lo) / (hi - lo), 0.0), 1.0)

    def __call__(self, x: float) -> float:
        lo, hi = self.out_range
        return lo + self.unit(x) * (hi - lo)

    def spec_tail(self) -> list[float]:
        return [*self.in_range, *self.out_range]


class ExpCurve(LinearCurve):
    """Exponential warp: t in [0, 1] from in_range, y = out_min + (e^(k t) - 1) / (e^k - 1) (out_max - out_min).

    ``curvature`` k > 0 rises slowly then fast (a velocity curve), k < 0 the
    opposite, k = 0 is linear.
    """

    kind: Literal["exp"] = "exp"  # type: ignore[assignment]
    curvature: float = Field(default=4.0, ge=-50, le=50)

    def __call__(self, x: float) -> float:
        t = self.unit(x)
        k = self.curvature
        w = t if abs(k) < 1e-9 else math.expm1(k * t) / math.expm1(k)
        lo, hi = self.out_range
        return lo + w * (hi - lo)

    def spec_tail(self) -> list[float]:
        return [*self.in_range, *self.out_range, self.curvature]


class TableCurve(_Model):
    """Piecewise linear through (x, y) points (x increasing); constant beyond the ends."""

    kind: Literal["table"] = "table"
    points: list[tuple[float, float]] = Field(min_length=2)

    @field_validator("points")
    @classmethod
    def _increasing(cls, value: list[tuple[float, float]]) -> list[tuple[float, float]]:
        xs = [p[0] for p in value]
        if any(b <= a for a, b in zip(xs, xs[1:], strict=False)):
            raise ValueError("table x values must increase")
        for _, y in value:
            _sendable(y, "table y value")
        return value

    def __call__(self, x: float) -> float:
        xs = np.fromiter((p[0] for p in self.points), float)
        ys = np.fromiter((p[1] for p in self.points), float)
        return float(np.interp(x, xs, ys))

    def spec_tail(self) -> list[float]:
        return [v for p in self.points for v in p]


Curve = Annotated[LinearCurve | ExpCurve | TableCurve, Field(discriminator="kind")]

OscType = Literal["auto", "i", "f", "s"]


class ArgSpec(_Model):
    """One value built from an impact: a feature (through an optional curve) or a constant."""

    feature: str | None = None
    value: int | float | str | None = None
    curve: Curve | None = None
    type: OscType = "auto"

    @model_validator(mode="after")
    def _check(self) -> ArgSpec:
        if (self.feature is None) == (self.value is None):
            raise ValueError("an argument is either a feature or a constant value")
        if self.feature is not None:
            if self.feature not in FEATURES:
                raise ValueError(f"unknown impact feature {self.feature!r} (known: {', '.join(sorted(FEATURES))})")
            if self.curve is not None and self.feature in STRING_FEATURES:
                raise ValueError(f"feature {self.feature!r} is a string: no curve applies")
        elif self.curve is not None:
            raise ValueError("a constant takes no curve")
        elif isinstance(self.value, int) and self.type in ("auto", "i") and not INT32_MIN <= self.value <= INT32_MAX:
            raise ValueError(f"{self.value} does not fit an OSC int32")
        elif isinstance(self.value, int | float) and self.type in ("auto", "f"):
            _sendable(self.value, "constant")
        if self.type in ("i", "f") and (
            self.feature in STRING_FEATURES or (self.value is not None and isinstance(self.value, str))
        ):
            raise ValueError("a string cannot be sent as a number")
        return self

    def evaluate(self, impact: ImpactFeatures) -> int | float | str:
        """The OSC argument for ``impact``; raises MappingError when it cannot be built."""
        value: int | float | str
        if self.feature is None:
            assert self.value is not None
            value = self.value
        else:
            value = impact.feature(self.feature)
            if self.curve is not None:
                value = self.curve(float(value))
        if isinstance(value, float) and not math.isfinite(value):
            raise MappingError(f"{self.to_spec()}: value is not finite")
        if self.type == "f" or (self.type == "auto" and isinstance(value, float)):
            assert not isinstance(value, str)
            try:
                _sendable(value, "value")
            except ValueError as exc:
                raise MappingError(f"{self.to_spec()}: {exc}") from None
        if self.type == "i" or (self.type == "auto" and isinstance(value, int)):
            assert not isinstance(value, str)
            whole = int(round(value))
            if not INT32_MIN <= whole <= INT32_MAX:
                raise MappingError(f"{self.to_spec()}: {whole} does not fit an OSC int32")
            return whole
        if self.type == "f":
            assert not isinstance(value, str)
            return float(value)
        if self.type == "s":
            return value if isinstance(value, str) else f"{value:g}"
        return value

    def to_spec(self) -> str:
        """The one-string form (module docstring)."""
        if self.feature is None:
            text = f"={self.value}"
        else:
            text = self.feature
            if self.curve is not None:
                text += ":" + ":".join([self.curve.kind, *(_spec_number(v) for v in self.curve.spec_tail())])
        return text if self.type == "auto" else f"{text}@{self.type}"

    @classmethod
    def parse(cls, text: str) -> ArgSpec:
        """Parse the one-string form; raises MappingError with the reason."""
        body, _, osc_type = text.strip().partition("@")
        if osc_type and osc_type not in ("i", "f", "s"):
            raise MappingError(f"{text!r}: type suffix must be @i, @f or @s")
        type_: OscType = osc_type if osc_type in ("i", "f", "s") else "auto"  # type: ignore[assignment]
        try:
            if body.startswith("="):
                return cls(value=_constant(text, body[1:], type_), type=type_)
            name, *rest = body.split(":")
            curve: LinearCurve | ExpCurve | TableCurve | None = None
            if rest:
                kind, numbers = rest[0], _curve_numbers(text, body, rest)
                if kind == "linear":
                    if len(numbers) != 4:
                        raise MappingError(f"{text!r}: linear takes IN_MIN:IN_MAX:OUT_MIN:OUT_MAX")
                    curve = LinearCurve(in_range=(numbers[0], numbers[1]), out_range=(numbers[2], numbers[3]))
                elif kind == "exp":
                    if len(numbers) not in (4, 5):
                        raise MappingError(f"{text!r}: exp takes IN_MIN:IN_MAX:OUT_MIN:OUT_MAX[:CURVATURE]")
                    extra = {"curvature": numbers[4]} if len(numbers) == 5 else {}
                    curve = ExpCurve(in_range=(numbers[0], numbers[1]), out_range=(numbers[2], numbers[3]), **extra)
                elif kind == "table":
                    if len(numbers) < 4 or len(numbers) % 2:
                        raise MappingError(f"{text!r}: table takes X0:Y0:X1:Y1[...] (two points or more)")
                    curve = TableCurve(points=list(zip(numbers[::2], numbers[1::2], strict=True)))
                else:
                    raise MappingError(f"{text!r}: unknown curve {kind!r} (linear, exp, table)")
            return cls(feature=name, curve=curve, type=type_)
        except MappingError:
            raise
        except ValueError as exc:  # float() or pydantic
            raise MappingError(f"{text!r}: {_first_line(exc)}") from None


def _spec_number(value: float) -> str:
    """The shortest text that parses back to ``value`` exactly ('127', '0.1234567', '1e-05'): a listed spec
    re-added as is must map the same (``:g`` kept six digits, so 0.1234567 came back as 0.123457)."""
    text = repr(float(value))
    return text[:-2] if text.endswith(".0") else text


def _curve_numbers(text: str, body: str, fields: list[str]) -> list[float]:
    """The numbers of a curve (``fields``: its kind then its numbers, from ``body``, the spec before any ``@``);
    MappingError naming the one that is not a number, and the ``@`` form of an OSC type written as a field
    (``velocity:linear:0:10:0:127:i`` for ``...:127@i``)."""
    last = fields[-1]
    if last in ("i", "f", "s"):  # the type where a number (or the curve) belongs
        fixed = body.rpartition(":")[0] + "@" + last
        raise MappingError(f"{text!r}: the OSC type is written after @, not as a field: {fixed!r}")
    numbers = []
    for i, field in enumerate(fields[1:], 1):
        try:
            numbers.append(float(field))
        except ValueError:
            raise MappingError(f"{text!r}: {fields[0]}'s value {i}, {field!r}, is not a number") from None
    return numbers


def _constant(text: str, body: str, osc_type: str) -> int | float | str:
    """The value of the constant ``=body`` (spec ``text``): an int, else a float, else a string; always the string
    when sent as one (``@s``: ``=1e39@s`` had been the float 1e39). A number no OSC float carries (``=1e400``,
    ``=nan``, ``=inf``) raises MappingError (it was taken as the string '1e400')."""
    if osc_type == "s":
        return body
    for convert in (int, float):
        try:
            value = convert(body)
        except ValueError:
            continue
        if isinstance(value, float) and not math.isfinite(value):
            raise MappingError(f"{text!r}: constant {body!r} is not a finite number, which an OSC float must be "
                               f"(within ±{FLOAT32_MAX:.4g}; a string is sent with @s: '={body}@s')")
        return value
    return body


def _first_line(exc: Exception) -> str:
    """The reason on one line: pydantic's first complaint (its report's last line is a link to its docs)."""
    return one_line(exc) or type(exc).__name__


# impact fields a route may map, with the Impact message's ranges
MAPPABLE_FIELDS: dict[str, tuple[float, float]] = {
    "r": (0.0, 2.0),
    "theta": (-7.0, 7.0),
    "velocity": (0.0, 100.0),
    "impulse": (0.0, FLOAT32_MAX),
    "peak_force": (0.0, FLOAT32_MAX),
    "duration": (0.0, 1.0),
}


def parse_instruments(text: str) -> list[str]:
    """'*' or '' -> [] (every instrument); 'a, b' -> ['a', 'b']."""
    names = [n.strip() for n in text.split(",") if n.strip()]
    return [] if names in ([], ["*"]) else names


def format_instruments(names: list[str]) -> str:
    return ",".join(names) if names else "*"


class Route(_Model):
    """Where impacts go, for which instruments, with which Impact fields mapped.

    An empty ``fields`` is the one-to-one physical mapping. ``ends`` also sends
    ``/batteur/impact/end`` and ``/batteur/damping`` to this target.
    """

    to: str = Field(min_length=1, max_length=128, description="role name or host:port")
    instruments: list[str] = Field(default_factory=list, description="kit object ids; empty: every instrument")
    fields: dict[str, ArgSpec] = Field(default_factory=dict, description="Impact field -> spec")
    ends: bool = True

    @field_validator("fields")
    @classmethod
    def _mappable(cls, value: dict[str, ArgSpec]) -> dict[str, ArgSpec]:
        for name, spec in value.items():
            if name not in MAPPABLE_FIELDS:
                raise ValueError(f"field {name!r} cannot be mapped (mappable: {', '.join(MAPPABLE_FIELDS)})")
            if spec.feature in STRING_FEATURES or isinstance(spec.value, str) or spec.type == "s":
                raise ValueError(f"field {name!r} is a number; {spec.to_spec()!r} is a string")
        return value

    _target = field_validator("to")(_check_target)

    def matches(self, instrument: str) -> bool:
        return not self.instruments or instrument in self.instruments


class RegisteredMessage(_Model):
    """A message registered at run time: sent to ``to`` on every matching impact."""

    name: str = Field(pattern=r"^[A-Za-z0-9_.-]{1,64}$")
    to: str = Field(min_length=1, max_length=128, description="role name or host:port")
    address: str = Field(pattern=r"^/[^\s#*?,\[\]{}]*$", max_length=128, description="OSC address")
    instruments: list[str] = Field(default_factory=list, description="kit object ids; empty: every instrument")
    when: Literal["onset", "end"] = "onset"
    args: list[ArgSpec] = Field(default_factory=list, max_length=MAX_ARGS)
    repeat: int = Field(default=1, ge=1, le=16, description="copies sent (receivers without de-duplication: 1)")

    _target = field_validator("to")(_check_target)

    def matches(self, instrument: str) -> bool:
        return not self.instruments or instrument in self.instruments

    def build(self, impact: ImpactFeatures) -> list[int | float | str]:
        """The argument list for ``impact``; raises MappingError."""
        return [spec.evaluate(impact) for spec in self.args]


def default_routes() -> list[Route]:
    """The one-to-one physical mapping: every impact as is to sound and to graphics."""
    return [Route(to="sound"), Route(to="graphics")]
