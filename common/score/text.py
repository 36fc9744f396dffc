"""The plain-text drum score format (documented in docs/score-format.md).

Example::

    # a rock beat
    tempo 100
    meter 4/4
    HH |x.x.x.x.x.x.x.x.|
    SN |....X.......X...|
    BD |x.......x.x.....|
    repeat 2

Rows of one block (consecutive grid lines) share a grid; a blank line or a
directive ends a block, and the next block starts where it ended. Errors raise
:class:`ScoreError` with the line number.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from common.gesture.plan import Grip, Nuance
from common.kit import EventType, Limb
from common.score.events import DrumEvent, Score, ScoreError, remove_duplicates

ALIASES: dict[str, EventType] = {
    "BD": EventType.BASS,
    "KICK": EventType.BASS,
    "SN": EventType.SNARE,
    "SD": EventType.SNARE,
    "RS": EventType.RIM,
    "HT": EventType.HIGHTOM,
    "T1": EventType.HIGHTOM,
    "MT": EventType.MIDTOM,
    "T2": EventType.MIDTOM,
    "FT": EventType.FLOORTOM,
    "T3": EventType.FLOORTOM,
    "CR": EventType.CRASH,
    "CC": EventType.CRASH,
    "RD": EventType.RIDE,
    "RB": EventType.RIDEBELL,
    "SP": EventType.SPLASH,
    "CH": EventType.CHINA,
    "HO": EventType.HIHATOPEN,
    "OH": EventType.HIHATOPEN,
    "HH": EventType.HIHATCLOSED,
    "HC": EventType.HIHATCLOSED,
    "HP": EventType.HIHATPEDAL,
    "PH": EventType.HIHATPEDAL,
    "CB": EventType.COWBELL,
}
"""Short row names; the 15 event type names (SNARE, RIDEBELL, ...) work too."""

CELL_VELOCITY: dict[str, float] = {"x": 0.7, "o": 0.7, "X": 1.0, "O": 1.0, "g": 0.3}
"""Grid cell characters and their velocity; digits 1-9 give velocity n/9; '.' and '-' are rests."""

NUANCE_LETTERS: dict[str, Nuance] = {
    "l": Nuance.LEGATO,
    "t": Nuance.TENUTO,
    "a": Nuance.ACCENT,
    "v": Nuance.VERTICAL_ACCENT,
    "s": Nuance.STACCATO,
}
STICKING = {"R": Limb.RIGHT_HAND, "L": Limb.LEFT_HAND}
FOOT_EVENTS = {EventType.BASS, EventType.HIHATPEDAL}


def event_type(name: str) -> EventType | None:
    """Event type for a row or note name (alias or full name, case-insensitive), None if unknown."""
    key = name.upper()
    if key in EventType.__members__:
        return EventType[key]
    return ALIASES.get(key)


class TextScore(Score):
    """A :class:`Score` read from text, with the global grip and nuance it asked for."""

    grip: Grip | None = None
    nuance: Nuance | None = None


class _Tempo:
    """Beats -> seconds with tempo changes (bpm) at beat positions."""

    def __init__(self) -> None:
        self.points: list[tuple[float, float, float]] = [(0.0, 0.0, 120.0)]  # beat, seconds, bpm

    def set(self, beat: float, bpm: float) -> None:
        b0, s0, old = self.points[-1]
        seconds = s0 + (beat - b0) * 60.0 / old
        if beat == b0:
            self.points[-1] = (b0, s0, bpm)
        else:
            self.points.append((beat, seconds, bpm))

    def seconds(self, beat: float) -> float:
        for b0, s0, bpm in reversed(self.points):
            if beat >= b0:
                return s0 + (beat - b0) * 60.0 / bpm
        return beat * 0.5


def _split_cells(row: str, lineno: int) -> tuple[list[str], int]:
    """Cells of a grid row and its bar count ('|' separates bars)."""
    bars = [b for b in row.strip().strip("|").split("|")]
    if any(not b for b in bars):
        raise ScoreError(f"line {lineno}: empty bar in grid row")
    widths = {len(b) for b in bars}
    if len(widths) != 1:
        raise ScoreError(f"line {lineno}: bars of one row must have the same number of cells (got {sorted(widths)})")
    return [c for b in bars for c in b], len(bars)


def parse_text(text: str, source: str = "text") -> TextScore:
    """Parse the plain-text score format into a score (seconds, velocities in [0, 1])."""
    tempo = _Tempo()
    beats_per_bar = 4.0
    position = 0.0  # beats
    events: list[DrumEvent] = []
    block: list[tuple[int, str, str]] = []  # lineno, name, cells
    last_block: list[DrumEvent] = []  # events of the last block, in beats (time field holds beats)
    last_block_beats = 0.0
    grip: Grip | None = None
    nuance: Nuance | None = None

    def flush() -> None:
        nonlocal position, block, last_block, last_block_beats
        if not block:
            return
        grid: dict[str, tuple[list[str], int, int]] = {}
        for lineno, name, row in block:
            cells, bars = _split_cells(row, lineno)
            grid[name] = (cells, bars, lineno)
        sizes = {(len(c), b) for c, b, _ in grid.values()}
        if len(sizes) != 1:
            first = block[0][0]
            raise ScoreError(f"line {first}: rows of one block must have the same bars and cells, got {sorted(sizes)}")
        n_cells, n_bars = sizes.pop()
        cell_beats = beats_per_bar * n_bars / n_cells
        sticking = grid.pop("ST", None)
        nuances = grid.pop("NU", None)
        block_events: list[DrumEvent] = []
        for name, (cells, _, lineno) in grid.items():
            ev = event_type(name)
            if ev is None:
                raise ScoreError(f"line {lineno}: unknown instrument {name!r} (use an event type or an alias)")
            for k, ch in enumerate(cells):
                if ch in ".-":
                    continue
                if ch in CELL_VELOCITY:
                    vel = CELL_VELOCITY[ch]
                elif ch.isdigit() and ch != "0":
                    vel = int(ch) / 9.0
                else:
                    raise ScoreError(f"line {lineno}: cell {k + 1}: unknown character {ch!r}")
                limb = None
                if sticking is not None and sticking[0][k] in STICKING and ev not in FOOT_EVENTS:
                    limb = STICKING[sticking[0][k]]
                note_nuance = None
                if nuances is not None and nuances[0][k] in NUANCE_LETTERS:
                    note_nuance = NUANCE_LETTERS[nuances[0][k]]
                block_events.append(DrumEvent(k * cell_beats, ev, vel, None, limb, note_nuance))
        _place(block_events, position)
        last_block, last_block_beats = block_events, n_bars * beats_per_bar
        position += last_block_beats
        block = []

    def _place(evs: list[DrumEvent], start: float) -> None:
        for e in evs:
            events.append(DrumEvent(tempo.seconds(start + e.time), e.event, e.velocity, e.pitch, e.limb, e.nuance))

    for lineno, raw_line in enumerate(text.splitlines(), start=1):
        line = raw_line.split("#", 1)[0].rstrip()
        if not line.strip():
            flush()
            continue
        head, _, rest = line.strip().partition(" ")
        rest = rest.strip()
        if "|" in rest:
            block.append((lineno, head.upper(), rest))
            continue
        flush()
        word = head.lower()
        try:
            if word == "tempo":
                bpm = float(rest)
                if not 10 <= bpm <= 400:
                    raise ScoreError(f"line {lineno}: tempo {bpm} outside 10..400 bpm")
                tempo.set(position, bpm)
            elif word == "meter":
                num, _, den = rest.partition("/")
                beats_per_bar = float(num)
                if beats_per_bar <= 0 or not den.strip().isdigit():
                    raise ValueError(rest)
            elif word == "repeat":
                count = int(rest)
                if count < 1 or not last_block_beats:
                    raise ScoreError(f"line {lineno}: repeat needs a count >= 1 after a grid block")
                for _ in range(count):
                    _place(last_block, position)
                    position += last_block_beats
            elif word == "grip":
                grip = Grip(rest.lower())
            elif word == "nuance":
                nuance = Nuance(rest.lower().replace(" ", "_"))
            elif word in ("at", "note"):
                parts = rest.split()
                beat = float(parts[0])
                ev = event_type(parts[1]) if len(parts) > 1 else None
                if ev is None:
                    raise ScoreError(f"line {lineno}: note needs '<beat> <instrument> [velocity] [L|R]'")
                vel = float(parts[2]) if len(parts) > 2 else 0.7
                if not 0 <= vel <= 1:
                    raise ScoreError(f"line {lineno}: velocity {vel} outside [0, 1]")
                limb = STICKING.get(parts[3].upper()) if len(parts) > 3 else None
                events.append(DrumEvent(tempo.seconds(position + beat), ev, vel, None, limb, None))
            elif word == "rest":
                position += float(rest) if rest else beats_per_bar
            elif word in ("kit", "title"):
                pass
            else:
                raise ScoreError(f"line {lineno}: unknown directive {head!r}")
        except ScoreError:
            raise
        except (ValueError, IndexError) as exc:
            raise ScoreError(f"line {lineno}: cannot read {line.strip()!r} ({exc})") from exc
    flush()
    kept, removed = remove_duplicates(events)
    beats = np.array([tempo.seconds(b) for b in np.arange(0.0, position + 1e-9, 1.0)])
    score = TextScore(events=kept, beats=beats, duplicates=removed, source=source)
    score.grip = grip
    score.nuance = nuance
    return score


def read_score(path: str | Path, **kwargs: object) -> Score:
    """Read a score file: ``.mid``/``.midi``/``.smf`` as MIDI, anything else as the text format."""
    from common.score.midi import read_midi

    p = Path(path)
    if p.suffix.lower() in (".mid", ".midi", ".smf"):
        return read_midi(p, **kwargs)  # type: ignore[arg-type]
    if not p.is_file():
        raise ScoreError(f"{p}: no such file")
    try:
        text = p.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise ScoreError(f"{p}: not a text score (not UTF-8: {exc})") from exc
    try:
        return parse_text(text, source=str(p))
    except ScoreError as exc:
        raise ScoreError(f"{p}: {exc}") from exc
