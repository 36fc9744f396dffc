"""Impacts as a table: collected from a bus or a UDP listener, written as CSV.

One row per impact, de-duplicated by sequence number (interaction sends each
impact redundantly), with every feature the Impact message carries. An impact
is sent at its first contact step, when its impulse, peak force and duration
are not known yet (0); its ``/batteur/impact/end`` (same sender and sequence
number) brings them when the contact is over, and they replace the zeros.
"""

from __future__ import annotations

import csv
import heapq
import io
import math
from collections import deque
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO

from pydantic import ValidationError

from common.datafile import first_error, read_text
from common.input_file import file_problem
from common.messages import Impact, OscMessage
from common.messages.interaction import ImpactEnd

COLUMNS = list(Impact.model_fields)
OLDER_COLUMNS = [COLUMNS[: len(COLUMNS) - k] for k in range(1, len(Impact.APPENDED) + 1)]
"""The columns of an older render's impacts.csv, from before the Impact's appended fields (``openness``, 8 Dec):
read with their defaults."""


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
        if k is None or not _ends(end, self.impacts[k]):
            self.unmatched_ends += 1
            return
        self.impacts[k] = _completed(self.impacts[k], end)

    def sorted(self) -> list[Impact]:
        return sorted(self.impacts, key=lambda i: (i.time, i.instrument, i.seq))

    def write_csv(self, path: Path) -> None:
        write_impacts_csv(self.sorted(), path)


def _ends(end: ImpactEnd, impact: Impact) -> bool:
    """Whether ``end`` is that of ``impact`` (same sender and seq assumed): the same time and instrument."""
    return impact.time == end.time and impact.instrument == end.instrument


def _completed(impact: Impact, end: ImpactEnd) -> Impact:
    """``impact`` with its end's impulse, peak force and duration."""
    return impact.model_copy(update={"impulse": end.impulse, "peak_force": end.peak_force, "duration": end.duration})


def write_impacts_csv(impacts: list[Impact], path: Path) -> None:
    """Write impacts (rig times in seconds, SI units) as CSV with a header row."""
    with path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(COLUMNS)
        for impact in impacts:
            writer.writerow([_fmt(getattr(impact, c)) for c in COLUMNS])


HOLD_S = 1.0
"""A streamed row is written once the clock is this far past its impact's time, seconds: interaction sends an
impact at its first contact step, so no impact comes this late behind one already written."""
WAIT_S = 10.0
"""An impact whose contact is still going on holds back the rows after it up to this long past its time,
seconds; longer (a stick resting on a head), it is kept aside and its row put in place at the end."""
RECENT_S = 10.0
"""Written impacts are remembered this long past their time, seconds, so a late redundant copy is still one."""

_SortKey = tuple[float, str, int, int]
"""(time s, instrument, seq, arrival): the order of :meth:`ImpactLog.sorted`, ties in arrival order."""


class ImpactCsvStream:
    """impacts.csv written while the render goes on: the same bytes as :func:`write_impacts_csv` of
    :meth:`ImpactLog.sorted` for the same messages, holding only the impacts of the last seconds.

    Impacts are taken as :meth:`ImpactLog.add` takes them (first copy wins, ends complete them), each with the
    rig time ``now`` it arrived at (seconds). An impact whose time is ``hold_s`` behind ``now`` and whose end
    has come is written, in time order, to ``path`` + ``.rows``; one whose contact is still going on holds the
    rows after it back for up to ``wait_s``, and is then kept aside with its place in the order until its end
    comes. :meth:`finish` writes the header and the rows in order. An impact arriving behind one already
    written (never seen from interaction) makes :meth:`finish` sort every row again, so the file is right
    whatever the order of arrival.
    """

    def __init__(self, path: Path, hold_s: float = HOLD_S, wait_s: float = WAIT_S) -> None:
        self.path = Path(path)
        self.rows_path = self.path.with_name(self.path.name + ".rows")
        self.hold_s = hold_s
        self.wait_s = wait_s
        self.count = 0
        """Unique impacts taken."""
        self.unmatched_ends = 0
        self.peak_held = 0
        """Most impacts held in memory at once, not yet written (the contacts still going on included)."""
        self._pending: dict[tuple[str, int], Impact] = {}
        self._ended: set[tuple[str, int]] = set()
        """Pending impacts whose end has come."""
        self._heap: list[tuple[_SortKey, tuple[str, int]]] = []
        self._late: dict[tuple[str, int], tuple[int, int, Impact]] = {}
        """Written past while its contact went on: (rows before it, order, impact), completed by its end."""
        self._late_done: list[tuple[int, int, float, str]] = []
        """Kept-aside rows, complete: (rows before it, arrival order, time s, row text)."""
        self._recent: dict[tuple[str, int], Impact] = {}
        self._recent_order: deque[tuple[float, tuple[str, int]]] = deque()
        self._written = 0
        self._last_key: _SortKey | None = None
        self._disordered = False
        self._file: IO[str] | None = None

    def add(self, message: OscMessage, now: float, source: str = "") -> bool:
        """As :meth:`ImpactLog.add`, at rig time ``now`` (seconds); writes what is due."""
        if isinstance(message, ImpactEnd):
            self._complete(message, source)
        elif not isinstance(message, Impact):
            return False
        else:
            key = (source, message.seq)
            if key in self._pending or key in self._late or key in self._recent:
                return False
            sort_key = (message.time, message.instrument, message.seq, self.count)
            if self._last_key is not None and sort_key < self._last_key:
                self._disordered = True
            self.count += 1
            self._pending[key] = message
            heapq.heappush(self._heap, (sort_key, key))
            self.peak_held = max(self.peak_held, len(self._pending) + len(self._late) + len(self._late_done))
        self._write_due(now)
        return True

    def _complete(self, end: ImpactEnd, source: str) -> None:
        key = (source, end.seq)
        impact = self._pending.get(key)
        if impact is not None and _ends(end, impact):
            self._pending[key] = _completed(impact, end)
            self._ended.add(key)
            return
        late = self._late.get(key)
        if late is not None and _ends(end, late[2]):
            del self._late[key]  # complete now: its row waits for its place in finish()
            self._late_done.append((late[0], late[1], late[2].time, _row_text(_completed(late[2], end))))
            self._remember(key, late[2])
            return
        written = self._recent.get(key)
        if written is not None and _ends(end, written):
            return  # a copy of an end already folded in
        self.unmatched_ends += 1

    def _write_due(self, now: float, final: bool = False) -> None:
        """Write, in order, the impacts ``hold_s`` behind ``now`` (seconds) whose end came (``final``: all)."""
        heap = self._heap
        while heap and (final or heap[0][0][0] < now - self.hold_s):
            sort_key, key = heap[0]
            if not final and key not in self._ended and sort_key[0] >= now - self.wait_s:
                break  # its contact may end soon: the rows after it wait for its figures
            heapq.heappop(heap)
            impact = self._pending.pop(key)
            self._last_key = sort_key
            if not final and key not in self._ended:
                self._late[key] = (self._written, sort_key[3], impact)  # a long contact: its row is put in later
                continue
            self._ended.discard(key)
            self._write_row(sort_key, _row_text(impact))
            self._remember(key, impact)
        horizon = now - self.hold_s - RECENT_S
        while self._recent_order and self._recent_order[0][0] < horizon:
            self._recent.pop(self._recent_order.popleft()[1], None)

    def _remember(self, key: tuple[str, int], impact: Impact) -> None:
        self._recent[key] = impact
        self._recent_order.append((impact.time, key))

    def _write_row(self, sort_key: _SortKey, row: str) -> None:
        if self._file is None:
            self._file = self.rows_path.open("w+", encoding="utf-8", newline="")
        self._file.write(f"{sort_key[0]!r}\t{sort_key[3]}\t{row}")  # the key's time and arrival, exactly
        self._written += 1

    def finish(self) -> int:
        """Write impacts.csv (the impacts still going on with their figures unknown, 0); returns the row count."""
        try:
            self._write_due(math.inf, final=True)
            for position, order, impact in self._late.values():  # contacts still going on when the render ended
                self._late_done.append((position, order, impact.time, _row_text(impact)))
            self._late.clear()
            with self.path.open("w", newline="", encoding="utf-8") as out:
                out.write(_row_text(COLUMNS))
                if self._disordered:
                    out.writelines(self._all_rows_sorted())
                else:
                    self._merge_rows(out)
            return self.count
        finally:
            self.close()

    def _merge_rows(self, out: IO[str]) -> None:
        """The written rows, each kept-aside row put back at its place."""
        late = sorted(self._late_done)
        k = 0
        rows = self._rows()
        for position in range(self._written + 1):
            while k < len(late) and late[k][0] == position:
                out.write(late[k][3])
                k += 1
            if position < self._written:
                out.write(next(rows)[2])

    def _rows(self) -> Iterator[tuple[float, int, str]]:
        """The written rows: (impact time s, arrival order, row text)."""
        if self._file is None:
            return
        self._file.seek(0)
        for line in self._file:
            time_s, order, row = line.split("\t", 2)
            yield float(time_s), int(order), row

    def _all_rows_sorted(self) -> list[str]:
        """Every row in impact order, read back (only after an impact came behind one written)."""
        seq_col, instrument_col = COLUMNS.index("seq"), COLUMNS.index("instrument")
        keyed: list[tuple[tuple[float, str, int, int], str]] = []
        for time_s, order, row in [*self._rows(), *((t, o, r) for _, o, t, r in self._late_done)]:
            fields = next(csv.reader([row]))
            keyed.append(((time_s, fields[instrument_col], int(fields[seq_col]), order), row))
        keyed.sort(key=lambda kv: kv[0])
        return [row for _, row in keyed]

    def close(self) -> None:
        """Drop the rows' file (idempotent; :meth:`finish` does it)."""
        if self._file is not None:
            self._file.close()
            self._file = None
        self.rows_path.unlink(missing_ok=True)


def _row_text(row: Impact | list[str]) -> str:
    """One CSV line as :func:`write_impacts_csv` writes it (line end included)."""
    buffer = io.StringIO()
    fields = row if isinstance(row, list) else [_fmt(getattr(row, c)) for c in COLUMNS]
    csv.writer(buffer).writerow(fields)
    return buffer.getvalue()


def read_impacts_csv(path: Path) -> list[Impact]:
    """Read a CSV written by :func:`write_impacts_csv`; raises ValueError naming the file on a bad row, or on a
    file that is not UTF-8 text or not CSV, or not a regular file (a pipe is never opened: it would wait for a
    writer)."""
    problem = file_problem(Path(path), "an impact log (CSV)")
    if problem is not None:
        raise ValueError(f"{path}: {problem}")
    try:
        reader = csv.DictReader(io.StringIO(read_text(path)))
    except ValueError as exc:  # not UTF-8 text
        raise ValueError(f"{path}: {exc}") from None
    try:
        if reader.fieldnames != COLUMNS and reader.fieldnames not in OLDER_COLUMNS:
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
