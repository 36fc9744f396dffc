"""Impacts as a table: collected from a bus or a UDP listener, written as CSV.

One row per impact, de-duplicated by sequence number (interaction sends each
impact redundantly), with every feature the Impact message carries.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass, field
from pathlib import Path

from pydantic import ValidationError

from common.datafile import first_error, read_text
from common.messages import Impact, OscMessage

COLUMNS = list(Impact.model_fields)


@dataclass
class ImpactLog:
    """Unique impacts in arrival order (first copy of each sequence number wins)."""

    impacts: list[Impact] = field(default_factory=list)
    _seen: set[tuple[str, int]] = field(default_factory=set)

    def add(self, message: OscMessage, source: str = "") -> bool:
        """Record an impact; False for anything else or a redundant copy."""
        if not isinstance(message, Impact):
            return False
        key = (source, message.seq)
        if key in self._seen:
            return False
        self._seen.add(key)
        self.impacts.append(message)
        return True

    def sorted(self) -> list[Impact]:
        return sorted(self.impacts, key=lambda i: (i.time, i.instrument, i.seq))

    def write_csv(self, path: Path) -> None:
        write_impacts_csv(self.sorted(), path)


def write_impacts_csv(impacts: list[Impact], path: Path) -> None:
    """Write impacts (rig times in seconds, SI units) as CSV with a header row."""
    with path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(COLUMNS)
        for impact in impacts:
            writer.writerow([_fmt(getattr(impact, c)) for c in COLUMNS])


def read_impacts_csv(path: Path) -> list[Impact]:
    """Read a CSV written by :func:`write_impacts_csv`; raises ValueError naming the file on a bad row, or on a
    file that is not UTF-8 text or not CSV."""
    try:
        reader = csv.DictReader(io.StringIO(read_text(path)))
    except ValueError as exc:  # not UTF-8 text
        raise ValueError(f"{path}: {exc}") from None
    try:
        if reader.fieldnames != COLUMNS:
            raise ValueError(f"{path}: expected columns {COLUMNS}, got {reader.fieldnames}")
        impacts = []
        for row in reader:
            try:
                impacts.append(Impact.model_validate(row))
            except ValidationError as exc:  # the first problem of the row, on one line
                raise ValueError(f"{path}: line {reader.line_num}: {first_error(exc)}") from None
        return impacts
    except csv.Error as exc:
        raise ValueError(f"{path}: not a CSV file ({exc})") from None


def _fmt(value: object) -> str:
    return f"{value:.9g}" if isinstance(value, float) else str(value)
