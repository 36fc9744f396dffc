"""``argparse`` types for the command line and the benchmarks: numbers that must be positive, refused with a
usage error (exit 2) naming the option instead of failing later with a division by zero or an empty run."""

from __future__ import annotations

import argparse
import math
import re

NEGATIVE_VALUE = re.compile(r"^-(?:\.?\d|inf|nan)", re.IGNORECASE)
"""A value that starts with '-' and is a number or begins as one (``-1e-3``, ``-.5``, ``-inf``, ``--strikes -1:3``),
not an option: argparse takes all but ``-1`` and ``-1.5`` for options ("expected one argument", "unrecognized
arguments"), where the value's own check should say what is wrong with it."""


def take_negative_values(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """``parser``, reading the arguments :data:`NEGATIVE_VALUE` matches as values (none of its options may look
    like one)."""
    parser._negative_number_matcher = NEGATIVE_VALUE  # argparse has no public way to say which values these are
    return parser


def number(text: str) -> float:
    """Any number (``nan`` and ``inf`` too: the types below refuse what they must)."""
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None


def whole(text: str) -> int:
    """Any whole number."""
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None


def positive(text: str) -> float:
    """A positive, finite number (a duration, a rate, a speed factor)."""
    value = number(text)
    if not 0.0 < value < math.inf:
        raise argparse.ArgumentTypeError(f"{text!r}: give a positive finite number")
    return value


seconds = positive
"""A positive, finite number of seconds."""
hertz = positive
"""A positive, finite rate, Hz."""


def non_negative(text: str) -> float:
    """A finite number of at least 0 (seconds that may be none, a weight)."""
    value = number(text)
    if not 0.0 <= value < math.inf:
        raise argparse.ArgumentTypeError(f"{text!r}: give a finite number of at least 0")
    return value


def unit(text: str) -> float:
    """A number from 0 to 1 (a share, a wet/dry balance)."""
    value = number(text)
    if not 0.0 <= value <= 1.0:  # also refuses nan
        raise argparse.ArgumentTypeError(f"{text!r}: give a number from 0 to 1")
    return value


def count(text: str) -> int:
    """A whole number of at least 1."""
    value = whole(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: give at least 1")
    return value


def whole_non_negative(text: str) -> int:
    """A whole number of at least 0 (a count where 0 means none, or skip)."""
    value = whole(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"{text!r}: give a whole number of at least 0")
    return value


seed = whole_non_negative
"""A random seed: a whole number of at least 0 (NumPy refuses negative seeds)."""
