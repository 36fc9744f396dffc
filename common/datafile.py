"""Reading the project's data files (YAML, JSON, TOML) with errors of one line that say what is wrong and where.

YAML's own messages quote the lines around the problem over several lines, and a file that is not UTF-8
text raises ``UnicodeDecodeError``; every reader of kits, settings, interaction configurations and poses
reports these the same way through :func:`parse_file` (BVH files through :func:`read_text`), and pydantic's
first complaint about what was read through :func:`first_error` (how many more: :func:`more_errors`).
"""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from pydantic import ValidationError
from pydantic_core import ErrorDetails

BOUND_WORDS = {"greater_than": ("gt", "more than"), "greater_than_equal": ("ge", "at least"),
               "less_than": ("lt", "less than"), "less_than_equal": ("le", "at most")}
"""pydantic's complaints about a number outside its bounds -> (the bound's key in the error's context, the words
:func:`error_message` says it with)."""
BOUND_ERRORS = frozenset(BOUND_WORDS)
"""pydantic's complaints about a number outside its bounds: a NaN fails every comparison and gets one of them."""
SAYS_THE_INPUT = BOUND_ERRORS | {"literal_error"}
"""Complaints :func:`first_error` follows with the value given (``, got 5``): pydantic's own words omit it."""


def parse_file(path: Path) -> Any:
    """The data of ``path``: JSON for ``.json``, TOML for ``.toml``, else YAML.

    Raises ``OSError`` when the file cannot be read, and ``ValueError`` (one line, without the path, for the
    caller to prefix) when it is not UTF-8 text or not valid in its format, e.g. ``not valid YAML: expected
    ',' or ']', but got '<stream end>' at line 2, column 1``.
    """
    kind = {".json": "JSON", ".toml": "TOML"}.get(path.suffix.lower(), "YAML")
    text = read_text(path)
    try:
        if kind == "JSON":
            return json.loads(text)
        if kind == "TOML":
            return tomllib.loads(text)
        return yaml.safe_load(text)
    except (ValueError, yaml.YAMLError) as exc:  # JSONDecodeError and TOMLDecodeError are ValueErrors
        raise ValueError(f"not valid {kind}: {one_line(exc)}") from None


def read_text(path: Path) -> str:
    """The UTF-8 text of ``path``. Raises ``OSError`` when it cannot be read and ``ValueError`` (one line,
    without the path) when it is not UTF-8 text, e.g. a binary file."""
    try:
        return path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise ValueError(f"not UTF-8 text ({exc.reason} at byte {exc.start})") from None


def first_error(exc: ValidationError) -> str:
    """The first problem pydantic found, on one line: ``field.path: message``; a required key missing beside a
    key the model does not take is said as the typo it likely is (:func:`misspelt_key`)."""
    errors = exc.errors()
    first = errors[0]
    typo = misspelt_key(first, errors)
    if typo is not None:
        return typo
    where = ".".join(str(p) for p in first.get("loc", ()))
    said = error_message(first)
    if first.get("type") in SAYS_THE_INPUT and said != NOT_FINITE:
        said += f", got {_shown(first.get('input'))}"
    return f"{where}: {said}" if where else said  # the whole input: no field


def more_errors(exc: ValidationError) -> int:
    """How many problems pydantic found besides the one :func:`first_error` says; a misspelt key's two (the key
    missing, the key not taken) are that one, not "(and 1 more)"."""
    errors = exc.errors()
    said = 2 if _misspelling(errors[0], errors) is not None else 1
    return max(len(errors) - said, 0)


def misspelt_key(first: ErrorDetails, errors: list[ErrorDetails]) -> str | None:
    """``objects.1: 'positon' is not a key here ('position' is missing: misspelt?)`` when ``first`` is a missing
    key and a key of the same mapping is not one the model takes; else None. pydantic lists the missing key
    first, and "Field required" alone hid the typo that caused it."""
    extra = _misspelling(first, errors)
    if extra is None:
        return None
    loc = tuple(first.get("loc", ()))
    where = ".".join(str(p) for p in loc[:-1])
    said = f"{tuple(extra.get('loc', ()))[-1]!r} is not a key here ({loc[-1]!r} is missing: misspelt?)"
    return f"{where}: {said}" if where else said


def _misspelling(first: ErrorDetails, errors: list[ErrorDetails]) -> ErrorDetails | None:
    """The error of a key the model does not take beside ``first`` when ``first`` is a missing key: the typo that
    caused it; else None."""
    loc = tuple(first.get("loc", ()))
    if first.get("type") != "missing" or not loc:
        return None
    for error in errors:
        other = tuple(error.get("loc", ()))
        if error.get("type") == "extra_forbidden" and other[:-1] == loc[:-1]:
            return error
    return None


VALUE_ERROR_PREFIX = "Value error, "
"""What pydantic puts before the message of a ``ValueError`` raised by a validator (a model's own check)."""


NOT_FINITE = "must be a finite number"


def error_message(error: ErrorDetails) -> str:
    """pydantic's message for one problem in plain words, the one place every caller (OSC refusals, settings,
    kits, impact logs) takes them from: a validator's own message without pydantic's ``Value error, ``; a bound
    as ``must be at most 2`` (``more than``, ``at least``, ``less than``), not "Input should be less than or equal
    to 2"; a choice as ``must be 'play', 'stop' or 'pause'``; and "must be a finite number" for a NaN refused by a
    bound, which pydantic describes as out of range though no range would take it. Without the value given
    (:func:`first_error` adds it; the settings say it their own way)."""
    kind = error.get("type")
    context = error.get("ctx") or {}
    if kind in BOUND_WORDS:
        if _is_nan(error.get("input")):
            return NOT_FINITE
        key, words = BOUND_WORDS[kind]
        if key in context:
            return f"must be {words} {_shown(context[key])}"
    if kind == "literal_error" and "expected" in context:
        return f"must be {context['expected']}"
    message = str(error.get("msg", "invalid"))
    return message.removeprefix(VALUE_ERROR_PREFIX) if kind == "value_error" else message


def _shown(value: object) -> str:
    """A value as a message quotes it: a number as written (``5``, not ``5.0``; a float32 off the wire to its 7
    digits, ``0.1``, not ``0.10000000149011612``), anything else as its repr, cut short past 40 characters (a
    whole datagram's string stays out of a one-line refusal)."""
    if isinstance(value, int) and not isinstance(value, bool):
        return str(value)
    if isinstance(value, float) and math.isfinite(value):
        if value.is_integer() and abs(value) < 1e16:  # 1000, not 1e+03
            return str(int(value))
        with np.errstate(over="ignore"):
            single = np.float32(value)
        return str(single) if float(single) == value else repr(value)  # numpy's shortest float32 digits
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _is_nan(value: object) -> bool:
    """Whether ``value`` is a NaN, as a float or as the text of one (a command-line flag, an environment
    variable)."""
    if isinstance(value, bool) or not isinstance(value, (float, int, str)):
        return False
    try:
        return math.isnan(float(value))
    except ValueError:
        return False


def one_line(exc: BaseException) -> str:
    """An error's message on one line: pydantic's first complaint (:func:`first_error`), YAML's problem and where,
    any other message with its line breaks folded."""
    if isinstance(exc, ValidationError):
        return first_error(exc)
    if isinstance(exc, yaml.MarkedYAMLError):
        mark = exc.problem_mark
        at = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        return f"{exc.problem or exc.context}{at}"
    return " ".join(str(exc).split())
