"""Impacts as a table: collected from a bus or a UDP listener, written as CSV.

One row per impact, de-duplicated by sequence number (interaction sends each
impact redundantly), with every feature the Impact message carries. An impact
is sent at its first contact step, when its impulse, peak force and duration
are not known yet (0); its ``/batteur/impact/end`` (same sender and sequence
number) brings them when the contact is over, and they replace the zeros.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass, field
from pathlib import Path

from pydantic import ValidationError

from common.datafile import first_error, read_text
from common.messages import Impact, OscMessage
from common.messages.interaction import ImpactEnd

COLUMNS = list(Impact.model_fields)


@dataclass
class ImpactLog:
    """Unique impacts in arrival order (first copy of each sequence number wins), completed by their ends."""

    impacts: list[Impact] = field(default_factory=list)
    _seen: dict[tuple[str, int], int] = field(default_factory=dict)
    """(sender, seq) -> index in ``impacts``."""
    unmatched_ends: int = 0
    """Impact ends whose impact was never recorded (lost, or sent before the log started): counted, dropped."""

    def add(self, message: OscMessage, source: str = "") -> bool:
        """Record an impact, or fold an impact end's figures into its impact; False for anything else or a
        redundant copy of an impact."""
        if isinstance(message, ImpactEnd):
            self._complete(message, source)
            return True
        if not isinstance(message, Impact):
            return False
        key = (source, message.seq)
        if key in self._seen:
            return False
        self._seen[key] = len(self.impacts)
        self.impacts.append(message)
        return True

    def _complete(self, end: ImpactEnd, source: str) -> None:
        """The impact's final impulse, peak force and duration (every copy of the end gives the same)."""
        k = self._seen.get((source, end.seq))
        if k is None or self.impacts[k].time != end.time or self.impacts[k].instrument != end.instrument:
            self.unmatched_ends += 1
            return
        self.impacts[k] = self.impacts[k].model_copy(
            update={"impulse": end.impulse, "peak_force": end.peak_force, "duration": end.duration})

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
