"""``argparse`` types for the command line and the benchmarks: numbers that must be positive, refused with a
usage error (exit 2) naming the option instead of failing later with a division by zero or an empty run."""

from __future__ import annotations

import argparse
import math


def positive(text: str) -> float:
    """A positive, finite number (a duration, a rate, a speed factor)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not 0.0 < value < math.inf:
        raise argparse.ArgumentTypeError(f"{text!r}: give a positive finite number")
    return value


seconds = positive
"""A positive, finite number of seconds."""
hertz = positive
"""A positive, finite rate, Hz."""


def count(text: str) -> int:
    """A whole number of at least 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: give at least 1")
    return value
