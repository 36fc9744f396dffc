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
directive ends a block, and the next block starts where it ended. Beats are quarter
notes, as in a MIDI file: ``tempo`` counts them a minute, a bar of ``meter N/D``
lasts N x 4/D of them, and ``at`` and ``rest`` count them. Errors raise
:class:`ScoreError` with the line number.
"""

from __future__ import annotations

import bisect
import difflib
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np

from common.datafile import read_text
from common.gesture.plan import Grip, Nuance
from common.kit import STRUCK_KINDS, EventType, Kit, Limb, load_kit
from common.score.events import (
    MAX_SCORE_BARS,
    MAX_SCORE_NOTES,
    MAX_SCORE_SECONDS,
    DrumEvent,
    Score,
    ScoreError,
    check_file,
    check_not_audio,
    double_key,
    hours,
    remove_duplicates,
    starts_as_midi,
    unicode_bom,
)
from common.score.gm import DRUM_MAP

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
    """A :class:`Score` read from text, with the global grip, nuance and kit it asked for."""

    grip: Grip | None = None
    nuance: Nuance | None = None
    kit: str | None = None
    """The ``kit NAME`` line's name: a shipped kit or a kit file (None: the score names none)."""
    kit_line: int | None = None
    """The line of the ``kit`` directive, for a message about its kit."""


DEFAULT_BPM = 120.0
"""The tempo until a ``tempo`` line, beats (quarter notes) per minute: a MIDI file's default."""


class _Tempo:
    """Beats -> seconds with tempo changes (bpm) at beat positions."""

    def __init__(self) -> None:
        self.points: list[tuple[float, float, float]] = [(0.0, 0.0, DEFAULT_BPM)]  # beat, seconds, bpm
        self.starts: list[float] = [0.0]  # the points' beats, increasing (a tempo is set where the score is)

    def set(self, beat: float, bpm: float) -> None:
        b0, s0, old = self.points[-1]
        seconds = s0 + (beat - b0) * 60.0 / old
        if beat == b0:
            self.points[-1] = (b0, s0, bpm)
        else:
            self.points.append((beat, seconds, bpm))
            self.starts.append(beat)

    def seconds(self, beat: float) -> float:
        # the last point at or before ``beat``, found by bisection: a scan per beat made a score with a tempo
        # line per bar quadratic (7 h of them took 50 s)
        k = bisect.bisect_right(self.starts, beat) - 1
        if k < 0:
            return beat * 0.5
        b0, s0, bpm = self.points[k]
        return s0 + (beat - b0) * 60.0 / bpm


ROW_NAMES_DOC = "docs/score-format.md, 'Row names'"
"""Where the instrument names are listed, for a message about one it does not know."""


def object_strokes(kit: Kit, object_id: str) -> dict[EventType, int | None]:
    """The strokes a score naming ``kit``'s object ``object_id`` may mean: each event type that strikes it, with the
    pitch that sends the event there (None: the event's own object; a pitch of the kit's ``note_objects``, General
    MIDI's, for a second piece: ``crash2`` 57), the event whose pedal it is for a footboard (``kick_pedal``: BASS).
    Empty for an object no note plays (the throne, a double pedal's second footboard, an object no event or
    ``note_objects`` pitch strikes)."""
    strokes: dict[EventType, int | None] = {}
    for event, spec in kit.events.items():
        if spec.object == object_id or (spec.pedal == object_id and event in FOOT_EVENTS):
            strokes[event] = None
    for pitch, target in sorted(kit.note_objects.items()):
        second = DRUM_MAP.get(pitch)
        if target == object_id and second is not None and second in kit.events and second not in strokes:
            strokes[second] = pitch
    return strokes


def object_stroke(kit: Kit, object_id: str) -> tuple[EventType, int | None] | None:
    """The event type and pitch a score's row or note naming ``kit``'s object ``object_id`` plays
    (:func:`object_strokes`): the one event type whose own object it is, else (an object only ``note_objects``
    pitches reach) its first pitch's, with that pitch. None for an unknown id, an object no note plays, or one that
    is the own object of several strokes (:func:`own_strokes`, the hi-hat open and closed: the stroke's name says
    which). An object reached by pitches of two event types (``note_objects {52: fx, 57: fx}``) is not ambiguous:
    naming CHINA or CRASH plays the china or the crash, never it (said "name the stroke" until 7 Dec)."""
    strokes = object_strokes(kit, object_id)
    own = own_strokes(strokes)
    if own:
        return (own[0], None) if len(own) == 1 else None
    return next(iter(strokes.items()), None)


def own_strokes(strokes: dict[EventType, int | None]) -> list[EventType]:
    """The event types among ``strokes`` (:func:`object_strokes`) whose own object (or pedal) it is."""
    return [event for event, pitch in strokes.items() if pitch is None]


def shadowed_by(kit: Kit, object_id: str) -> EventType | None:
    """The event type whose name or alias ``object_id`` is when that event's own object is another of ``kit``'s (a
    kit object ``ft``: ``ft`` is FLOORTOM, whose object is ``floortom``): a score naming it plays that event, never
    the object. None otherwise (``snare``, ``ride``: the event's own object; no event type's name)."""
    event = event_type(object_id)
    if event is None or event not in kit.events:
        return event
    return None if object_id in (kit.events[event].object, kit.events[event].pedal) else event


def shipped_kit_with(object_id: str, besides: str) -> str | None:
    """The first shipped kit other than ``besides`` a note naming ``object_id`` plays (:func:`object_stroke`), for
    an unknown instrument's message: a score naming ``crash2`` without its ``kit double_pedal`` line."""
    from common.kit import KITS_DIR

    for path in sorted(KITS_DIR.glob("*.yaml")):
        if path.stem == besides or not object_id.isidentifier():
            continue
        try:
            shipped = load_kit(path.stem, warn=False)
        except (FileNotFoundError, ValueError):
            continue
        if object_stroke(shipped, object_id) is not None:
            return shipped.name
    return None


def unknown_instrument(name: str, lineno: int, kit: Kit | None = None) -> ScoreError:
    """The error for an instrument name that is neither an event type, an alias nor (with ``kit``, the kit the
    score's object ids are looked up in) an object of the kit one stroke plays: the nearest names (those it starts,
    then the closest by spelling) and where the list is (it said "use an event type or an alias", with neither),
    then the kit's objects a note may name, which of them need a stroke's name (the hi-hat: HH or HO), and what to
    do for an object of the kit no note plays, or one of another shipped kit."""
    ids: list[str] = []  # the ids a note may name (an event type's name among them: snare, ride)
    listed = ""
    if kit is not None:
        shadowed = [(o.id, ev) for o in kit.objects if (ev := shadowed_by(kit, o.id)) is not None]
        ids = [o.id for o in kit.objects if o.id not in dict(shadowed)
               and (event_type(o.id) is not None or object_stroke(kit, o.id) is not None)]
        listed = f", and the objects of kit {kit.name!r}: {', '.join(ids)}"
        several = [(o.id, own_strokes(object_strokes(kit, o.id))) for o in kit.objects if event_type(o.id) is None]
        several = [(i, own) for i, own in several if len(own) > 1]  # those reached by pitches play the first
        if several:
            listed += " (" + "; ".join(f"{i} is struck by {_either([e.value for e in own])}"
                                       for i, own in several) + ": name the stroke)"
        if shadowed:  # 'ft' is FLOORTOM's alias: a row 'ft' plays floortom, never the object ft (was listed)
            listed += "; " + "; ".join(
                f"a row {i!r} plays {ev.value}{f' (on {kit.events[ev].object})' if ev in kit.events else ''}: a "
                f"score cannot name the object {i} (give it another id in the kit)" for i, ev in shadowed)
        named = next((o for o in kit.objects if o.id == name.lower()), None)
        if named is not None and not object_strokes(kit, named.id):
            if named.kind in STRUCK_KINDS:  # a kit designer's new object: a pitch of its own makes it playable
                listed += (f"; {named.id} is an object of kit {kit.name!r} no event type or note_objects pitch "
                           f"strikes: give it a General MIDI pitch in the kit's note_objects (a tom's 41 to 50, a "
                           f"cymbal's 49 to 59; {DRUM_MAP_DOC})")
            else:
                listed += f"; {named.id} is the kit's {named.kind}, which no note plays alone"
        elif named is None:
            elsewhere = shipped_kit_with(name.lower(), kit.name)
            if elsewhere is not None:  # the score's kit line left out, or another kit given
                listed += (f"; {name.lower()} is an object of kit {elsewhere!r}: play the score on it (a 'kit "
                           f"{elsewhere}' line)")
    names = [*EventType.__members__, *ALIASES]
    key = name.upper()
    stripped = key.strip(":;,.")  # 'HH:'
    near = [stripped] if stripped != key and event_type(stripped) is not None else []
    near += [n for n in names if len(key) >= 3 and n.startswith(key)]  # 'HIHAT': the three hi-hats
    near += difflib.get_close_matches(key, names, n=3, cutoff=0.6)
    near += difflib.get_close_matches(name.lower(), [i for i in ids if event_type(i) is None], n=3,
                                      cutoff=0.6)  # 'crash3': crash2 (crash is CRASH, said already)
    near = list(dict.fromkeys(near))[:4]
    hint = f": did you mean {_either(near)}?" if near else ""
    return ScoreError(f"line {lineno}: unknown instrument {name!r}{hint} (the names are the event types and their "
                      f"aliases: {ROW_NAMES_DOC}{listed})")


DRUM_MAP_DOC = "docs/score-format.md, 'Drum map'"


def _split_cells(row: str, lineno: int) -> tuple[list[str], int]:
    """Cells of a grid row and its bar count ('|' separates bars)."""
    bars = [b for b in row.strip().strip("|").split("|")]
    if any(not b for b in bars):
        raise ScoreError(f"line {lineno}: empty bar in grid row")
    odd = next((k for k, b in enumerate(bars) if len(b) != len(bars[0])), None)
    if odd is not None:  # named, against the first (was "(got [6, 8])", sorted, of no bar)
        raise ScoreError(f"line {lineno}: bar {odd + 1} has {len(bars[odd])} cells, bar 1 has {len(bars[0])} (the "
                         f"bars of one row have the same number of cells)")
    return [c for b in bars for c in b], len(bars)


def _note_cells(cells: list[str], lineno: int) -> int:
    """The number of notes in an instrument row; a cell that is neither a note nor a rest is an error."""
    notes = 0
    for k, ch in enumerate(cells):
        if ch in ".-":
            continue
        if ch not in CELL_VELOCITY and ch not in DIGITS:  # not str.isdigit: '²' is a digit to it, not to int()
            raise ScoreError(f"line {lineno}: cell {k + 1}: unknown character {ch!r} (use "
                             f"{', '.join(CELL_VELOCITY)}, a digit 1-9, or '.' or '-' for a rest)")
        notes += 1
    return notes


def _marks(name: str, rows: list[tuple[list[str], int, int]], allowed: str) -> list[str] | None:
    """The cells of the one ST or NU row of a block (None without one); a second row or another letter is an
    error (the row was silently ignored)."""
    if not rows:
        return None
    if len(rows) > 1:
        raise ScoreError(f"line {rows[1][2]}: a second {name} row in one block (the first is on line {rows[0][2]})")
    cells, _, lineno = rows[0]
    for k, ch in enumerate(cells):
        if ch not in allowed:
            raise ScoreError(f"line {lineno}: {name} cell {k + 1}: unknown character {ch!r} (use "
                             f"{', '.join(allowed[:-2])} or '.')")
    return cells


def _warn_foot_sticking(sticking: list[str], grid: dict[str, list[tuple[list[str], int, int]]], lineno: int,
                        warnings: list[str], events: dict[str, EventType], spelled: dict[str, str]) -> None:
    """Warn of ST marks whose column holds foot notes (BD, a hi-hat pedal) and no stick note: a foot plays them and
    the hand is ignored, as an ``at ... R`` line on a foot note says (they were ignored without a word).
    ``events``: each row name's event type; ``spelled``: each row name as written, an object id's said so
    (``kick_pedal``; KICK_PEDAL until 7 Dec), an event type's or alias's upper-case (BD)."""
    stick = set()
    feet: dict[int, list[str]] = {}
    for name, rows in grid.items():
        foot = events[name] in FOOT_EVENTS
        for cells, _, _ in rows:
            for k, ch in enumerate(cells):
                if ch in ".-":
                    continue
                if foot:
                    feet.setdefault(k, []).append(name if event_type(name) is not None else spelled[name])
                else:
                    stick.add(k)
    ignored = [k for k, ch in enumerate(sticking) if ch in STICKING and k in feet and k not in stick]
    if ignored:
        names = _either(sorted({n for k in ignored for n in feet[k]}))
        warnings.append(f"line {lineno}: ST {_cell_list(ignored)}: {names} is played by a foot; the "
                        f"hand{'s' * (len(ignored) > 1)} there {'are' if len(ignored) > 1 else 'is'} ignored")


def _cell_list(cells: list[int]) -> str:
    """'cell 3', 'cells 1-8', 'cells 1, 3, 5-6' for 0-based cell indices (increasing)."""
    runs: list[list[int]] = []
    for k in cells:
        if runs and k == runs[-1][-1] + 1:
            runs[-1].append(k)
        else:
            runs.append([k])
    parts = [f"{r[0] + 1}" if len(r) == 1 else f"{r[0] + 1}-{r[-1] + 1}" for r in runs]
    return f"cell{'s' * (len(cells) > 1)} {', '.join(parts)}"


def _size(cells: int, bars: int) -> str:
    """'8 cells in 2 bars' (a grid row's size, for a message)."""
    return f"{cells} cell{'s' * (cells != 1)} in {bars} bar{'s' * (bars != 1)}"


CELLS_A_BAR_DOC = "docs/score-format.md, 'Cells a bar'"
"""Where the rule of :func:`odd_cells_a_bar` is written, for its warning."""


def odd_cells_a_bar(cells: int, notes: float) -> bool:
    """Whether ``cells`` cells a bar are an unlikely split of a bar of ``notes`` notes of the meter (``meter N/D``:
    N), likely a typo (9 cells in 4/4), though played as written. A count is likely when every note of the meter
    gets the same whole number of cells or every cell the same whole number of notes (a multiple or a divisor of
    N: 8, 16, 12 or 20 in 4/4), or 2, 3 or 4 times such a count (duplets, triplets, quadruplets over the bar or a
    part of it: 3 or 6 in 4/4, 2 or 4 in 3/4), or, in a compound meter (N a multiple of 3 above 3: 6/8, 9/8,
    12/8), when every beat of three notes gets the same number of cells (10 in 6/8). A fractional N counts the
    notes of half (a quarter, ...) its D (2.5/4: 5 eighths); one that stays fractional is never odd.
    docs/score-format.md, 'Cells a bar'."""
    for _ in range(6):
        if notes == int(notes):
            break
        notes *= 2
    else:
        return False
    n = int(notes)
    if any(cells % k == 0 and (cells // k % n == 0 or n % (cells // k) == 0) for k in (1, 2, 3, 4)):
        return False
    return not (n % 3 == 0 and n > 3 and cells % (n // 3) == 0)


def _finite(value: str, what: str, lineno: int) -> float:
    """A number of a directive: finite (float() reads 'nan' and 'inf')."""
    number = float(value)
    if not math.isfinite(number):
        raise ScoreError(f"line {lineno}: {what} must be a finite number, got {value!r}")
    return number


DIRECTIVES = frozenset({"tempo", "meter", "repeat", "grip", "nuance", "at", "note", "rest", "kit", "title"})
"""The directive words (docs/score-format.md)."""
DIRECTIVE_NAMES = ["tempo", "meter", "repeat", "rest", "at (or note)", "grip", "nuance", "kit", "title"]
"""The directives as an unknown one lists them."""


def _either(values: list[str]) -> str:
    """'a, b or c'."""
    return f"{', '.join(values[:-1])} or {values[-1]}" if len(values) > 1 else values[0]


MAX_METER_UNIT = 64
"""The largest D of ``meter N/D`` (64th notes), and the shortest bar it takes (a 64th note, 1/16 beat)."""

DIRECTIVE_FORMS: dict[str, str] = {
    "tempo": "BPM: a number of beats (quarter notes) per minute, 10 to 400",
    "meter": "N/D: N notes of 1/D a bar (D 1 to 64, a bar at least a 64th note), e.g. 4/4, 6/8 or 2.5/4",
    "repeat": "N: a whole number of times, 1 or more",
    "rest": "[BEATS]: a number of beats, quarter notes (without it, a bar)",
    "grip": _either([g.value for g in Grip]),
    "nuance": _either([n.value for n in Nuance]),
    "kit": "NAME: a shipped kit's name (default, double_pedal, ...) or a kit file's path",
    "at": "BEAT NAME [VELOCITY, 0 to 1] [L|R]",
    "note": "BEAT NAME [VELOCITY, 0 to 1] [L|R]",
}
"""How each directive is written, said when one cannot be read (instead of Python's words about the value)."""

FIGURE_HINTS: dict[str, str] = {
    **dict.fromkeys(("swing", "shuffle"), "swing is written in triplet cells, 12 a bar of 4/4: HH |x.xx.xx.xx.x|"),
    **dict.fromkeys(("crescendo", "cresc", "decrescendo", "diminuendo", "dim", "dynamics", "dynamic", "volume",
                     "velocity", "accent"),
                    "dynamics are the cells' own: the digits 1-9 (n/9 of full), g ghost, x normal, X accent, "
                    "e.g. a crescendo SN |12345678|"),
    **dict.fromkeys(("accelerando", "accel", "ritardando", "rit", "rall", "rallentando"),
                    "a gradual tempo change is one tempo line a bar (or a beat), a block after each"),
    **dict.fromkeys(("bpm", "speed"), "the tempo is written tempo BPM, e.g. tempo 96"),
    **dict.fromkeys(("time", "signature", "timesig"), "the time signature is written meter N/D, e.g. meter 3/4"),
}
"""What an unknown directive a teacher might write is written as instead (its first word, lower case)."""

FIGURES_DOC = "docs/score-format.md, 'Writing common figures'"

RENDER_ONLY_GRIPS = ("american", "traditional")
"""Grips ``batteur render --grip`` takes but a score's ``grip`` line does not (the planner plans french or german;
the hands take these)."""

MARK_ROWS = ("ST", "NU")
"""The rows marking the notes of a block's instrument rows: sticking and nuance."""
DIGITS = "123456789"
STICK_MARKS = "RL.-"
NUANCE_MARKS = "ltavs.-"


def _row_without_bar_lines(head: str, rest: str) -> bool:
    """Whether the line ``head rest`` (no '|' in it) is a grid row written without its bar lines: an instrument
    (or ST, NU) name, then cells only (``HH x.x.x.x.``; not ``kick snare``, words, which stay an unknown
    directive)."""
    name = head.upper()
    if name in MARK_ROWS:
        allowed = STICK_MARKS if name == "ST" else NUANCE_MARKS
    elif event_type(head) is not None:
        allowed = "".join(CELL_VELOCITY) + DIGITS + ".-"
    else:
        return False
    return all(ch in allowed for ch in rest.replace(" ", ""))


def _kit_line(text: str) -> tuple[str, int] | None:
    """The kit the score's last ``kit`` line names and its line (as :func:`parse_text` keeps it; None: none), read
    before the score: a row may name the kit's objects above the line."""
    found = None
    for lineno, raw_line in enumerate(text.removeprefix("\ufeff").splitlines(), start=1):
        head, *more = raw_line.split("#", 1)[0].split(None, 1) or [""]
        if head.lower() == "kit" and more and more[0].strip():
            found = (more[0].strip(), lineno)
    return found


def parse_text(text: str, source: str = "text", kit: Kit | None = None) -> TextScore:
    """Parse the plain-text score format into a score (seconds, velocities in [0, 1]).

    A row or note may name an object of the kit by its id (``crash2``, ``floortom2``: :func:`object_stroke`), looked
    up in ``kit`` when given (the kit the score is played on), else in the kit of the score's ``kit`` line (from the
    folder of ``source``), else :data:`DEFAULT_KIT`; the kit is loaded only for a name that is no event type or
    alias. Its notes carry the event type and the pitch that strikes that object (:meth:`Kit.object_for`)."""
    tempo = _Tempo()
    beats_per_bar = 4.0
    count_unit = 1.0  # the meter's 1/D note, quarter notes: the beat a bar is counted in (Score.bar_units)
    meter = (4.0, "4/4")  # N, and the meter as written, for a warning about the cells of a bar
    position = 0.0  # beats
    last_note = 0.0  # the latest beat an `at` line placed a note on
    last_note_line = 0  # and its line
    events: list[DrumEvent] = []
    block: list[tuple[int, str, str]] = []  # lineno, name, cells
    last_block: list[DrumEvent] = []  # events of the last block, in beats (time field holds beats)
    last_block_beats = 0.0
    last_block_bar = 4.0  # the last block's beats per bar: a repeat plays its bars, whatever the meter is now
    last_block_unit = 1.0  # and its counted beat
    last_block_line = 0  # the last block's first line
    since_block: tuple[str, int] | None = None  # the first rest or `at` line after it (a repeat does not play it)
    bar_starts: list[float] = []  # where bars start, beats
    bar_units: list[float] = []  # each bar's counted beat, quarter notes
    last_bar = 4.0  # the length of the last bar started, as written (a rest may cut it short), beats
    warnings: list[str] = []
    grip: Grip | None = None
    nuance: Nuance | None = None
    kit_named: tuple[str, int] | None = None  # the kit line's name, line
    tempo_given = False
    ids_kit: list[Kit | None] = []  # the kit object ids are looked up in, once loaded (None: it cannot be)
    kit_failed: list[str] = []  # why it cannot be: "line 2: kit 'x', whose ..., cannot be loaded: no kit file 'x'"
    strokes: dict[str, tuple[EventType, int | None]] = {}  # an object id named -> its event type and pitch

    def objects_kit() -> Kit | None:
        """The kit the score's object ids name objects of: ``kit``, else its ``kit`` line's, else the default (one
        it cannot load: None, and ``kit_failed`` says why: an unknown name's error says it, the kit line being
        likelier wrong than the name; it was only "unknown instrument" until 7 Dec)."""
        if not ids_kit:
            if kit is not None:
                ids_kit.append(kit)
            else:
                line = _kit_line(text)
                named = TextScore(events=[], source=source)
                named.kit, named.kit_line = line if line is not None else (None, None)
                why: list[Exception] = []

                def load(name: str) -> Kit:
                    try:
                        return load_kit(name, warn=False)
                    except (FileNotFoundError, ValueError) as exc:
                        why.append(exc)
                        raise

                try:
                    ids_kit.append(load_score_kit(named, None, load=load))
                except (FileNotFoundError, ValueError) as exc:
                    ids_kit.append(None)
                    reason = why[0] if why else exc
                    which = f"line {line[1]}: kit {line[0]!r}" if line else f"kit {DEFAULT_KIT!r}"
                    kit_failed.append(f"{which}, whose objects a row may name, cannot be loaded: {reason}")
        return ids_kit[0]

    def instrument(name: str, lineno: int) -> tuple[EventType, int | None]:
        """The event type and pitch (None: the event's own object) of a row or note's instrument: an event type,
        an alias or an object id of :func:`objects_kit`; :func:`unknown_instrument`'s error otherwise."""
        ev = event_type(name)
        if ev is not None:
            return ev, None
        key = name.lower()
        if key not in strokes:
            found = objects_kit()
            stroke = None if found is None else object_stroke(found, key)
            if stroke is None:
                error = unknown_instrument(name, lineno, found)
                if kit_failed:  # the kit whose ids it may be: the kit line's own error, its line and why
                    error = ScoreError(f"{error}; {kit_failed[0]}")
                raise error
            strokes[key] = stroke
        return strokes[key]

    def check_until(beat: float, notes: int, lineno: int) -> None:
        """Refuse a score that would last longer or hold more notes than a score may, before making it."""
        if notes > MAX_SCORE_NOTES:
            raise ScoreError(f"line {lineno}: the score would hold {notes} notes, more than the "
                             f"{MAX_SCORE_NOTES} a score may hold")
        if tempo.seconds(beat) > MAX_SCORE_SECONDS:
            raise ScoreError(f"line {lineno}: the score would last {hours(tempo.seconds(beat))}, longer than the "
                             f"{hours(MAX_SCORE_SECONDS)} a score may last")

    def add_bars(start: float, length: float, bar: float | None = None, unit: float | None = None) -> None:
        """Bars of ``bar`` beats (default ``beats_per_bar``) counted in ``unit`` (default the meter's) from
        ``start`` over ``length`` beats (a last bar may be cut short); past :data:`MAX_SCORE_BARS` they are not
        kept."""
        nonlocal last_bar
        bar = beats_per_bar if bar is None else bar
        count = min(math.ceil(length / bar - 1e-9), MAX_SCORE_BARS - len(bar_starts))
        bar_starts.extend(start + k * bar for k in range(max(count, 0)))
        bar_units.extend([count_unit if unit is None else unit] * max(count, 0))
        if count > 0:
            last_bar = bar

    def flush() -> None:
        nonlocal position, block, last_block, last_block_beats, last_block_bar, last_block_line, since_block
        nonlocal last_block_unit
        if not block:
            return
        # rows by name, in the order names first appear: a name given twice plays both rows (the second one
        # replaced the first, whose notes were lost without a word)
        spelled: dict[str, str] = {}
        grid: dict[str, list[tuple[list[str], int, int]]] = {}
        n_cells = n_bars = 0
        for lineno, name, row in block:
            cells, bars = _split_cells(row, lineno)
            if not grid:
                n_cells, n_bars = len(cells), bars
            elif (len(cells), bars) != (n_cells, n_bars):  # named at the row that differs (was the block's first)
                raise ScoreError(f"line {lineno}: rows of one block must have the same bars and cells: this row has "
                                 f"{_size(len(cells), bars)}, the block's first row (line {block[0][0]}) "
                                 f"{_size(n_cells, n_bars)}")
            grid.setdefault(name.upper(), []).append((cells, bars, lineno))
            spelled.setdefault(name.upper(), name)  # an object id as written, for a message (crash2, not CRASH2)
        cell_beats = beats_per_bar * n_bars / n_cells
        marks = {name: grid.pop(name) for name in ("ST", "NU") if name in grid}
        if not grid:  # it added a silent bar: its notes are the rows above, without a blank line between
            name, rows = next(iter(marks.items()))
            raise ScoreError(f"line {rows[0][2]}: the {name} row has no instrument rows in its block: it marks the "
                             f"notes of the rows it follows, with no blank line or directive between")
        sticking = _marks("ST", marks.get("ST", []), STICK_MARKS)
        nuances = _marks("NU", marks.get("NU", []), NUANCE_MARKS)
        notes = len(events)
        played: dict[str, tuple[EventType, int | None]] = {}
        for name, rows in grid.items():
            played[name] = instrument(spelled[name], rows[0][2])
            notes += sum(_note_cells(cells, lineno) for cells, _, lineno in rows)
        if sticking is not None:
            _warn_foot_sticking(sticking, grid, marks["ST"][0][2], warnings,
                                {name: ev for name, (ev, _) in played.items()}, spelled)
        check_until(position + n_bars * beats_per_bar, notes, block[0][0])
        cells_a_bar = n_cells // n_bars
        if odd_cells_a_bar(cells_a_bar, meter[0]):  # played as written: tuplets are legitimate, typos likelier
            warnings.append(f"line {block[0][0]}: {cells_a_bar} cells a bar in {meter[1]}: not an even split of its "
                            f"{meter[0]:g} notes, played as {cells_a_bar} equal cells; a typo? ({CELLS_A_BAR_DOC})")
        block_events: list[DrumEvent] = []
        for name, rows in grid.items():
            ev, pitch = played[name]
            for cells, _, _ in rows:
                for k, ch in enumerate(cells):
                    if ch in ".-":
                        continue
                    vel = CELL_VELOCITY[ch] if ch in CELL_VELOCITY else int(ch) / 9.0
                    limb = None
                    if sticking is not None and sticking[k] in STICKING and ev not in FOOT_EVENTS:
                        limb = STICKING[sticking[k]]
                    note_nuance = None
                    if nuances is not None and nuances[k] in NUANCE_LETTERS:
                        note_nuance = NUANCE_LETTERS[nuances[k]]
                    block_events.append(DrumEvent(k * cell_beats, ev, vel, pitch, limb, note_nuance))
        _place(block_events, position)
        last_block, last_block_beats, last_block_bar = block_events, n_bars * beats_per_bar, beats_per_bar
        last_block_unit = count_unit
        last_block_line, since_block = block[0][0], None
        add_bars(position, last_block_beats)
        position += last_block_beats
        block = []

    def _place(evs: list[DrumEvent], start: float) -> None:
        for e in evs:
            events.append(DrumEvent(tempo.seconds(start + e.time), e.event, e.velocity, e.pitch, e.limb, e.nuance))

    def note(lineno: int, rest: str) -> None:
        """``at BEAT NAME [VELOCITY] [L|R]``."""
        nonlocal last_note, last_note_line
        parts = rest.split()
        if not 2 <= len(parts) <= 4:
            raise ScoreError(f"line {lineno}: note needs '<beat> <instrument> [velocity] [L|R]'")
        beat = _finite(parts[0], "the beat", lineno)
        ev, pitch = instrument(parts[1], lineno)
        if len(parts) == 3 and parts[2].upper() in STICKING:  # `at 0 SN L`: the velocity left out (was refused)
            parts.insert(2, "")
        vel = float(parts[2]) if len(parts) > 2 and parts[2] else 0.7
        if not 0 <= vel <= 1:
            midi = f" (MIDI's {vel:g} is {vel / 127:.2f})" if vel.is_integer() and 1 < vel <= 127 else ""
            raise ScoreError(f"line {lineno}: velocity {parts[2]} outside 0 to 1: velocities here are 0 to 1 (a grid's "
                             f"x is 0.7), not MIDI's 0-127{midi}")
        if len(parts) > 3 and parts[3].upper() not in STICKING:
            raise ScoreError(f"line {lineno}: the hand must be L or R, got {parts[3]!r}")
        limb = STICKING.get(parts[3].upper()) if len(parts) > 3 else None
        if limb is not None and ev in FOOT_EVENTS:  # as a sticking row skips them: a foot plays it
            warnings.append(f"line {lineno}: {parts[1]} is played by a foot; the hand {parts[3]} is ignored")
            limb = None
        if position + beat < 0:
            raise ScoreError(f"line {lineno}: beat {parts[0]} is before the start of the score "
                             f"({position:g} beats so far)")
        check_until(position + beat, len(events) + 1, lineno)
        events.append(DrumEvent(tempo.seconds(position + beat), ev, vel, pitch, limb, None))
        if position + beat >= last_note:
            last_note, last_note_line = position + beat, lineno

    lines = text.removeprefix("\ufeff").splitlines()  # a byte order mark, as Windows editors write
    for lineno, raw_line in enumerate(lines, start=1):
        line = raw_line.split("#", 1)[0].rstrip()
        if not line.strip():
            flush()
            continue
        head, *more = line.split(None, 1)  # any white space after the name: editors indent with tabs
        rest = more[0].strip() if more else ""
        if "|" in rest and head.lower() not in DIRECTIVES:  # no row is named like a directive: 'title A | B'
            block.append((lineno, head, rest))
            continue
        flush()
        word = head.lower()
        try:
            if word == "tempo":
                bpm = float(rest)
                if not 10 <= bpm <= 400:
                    raise ScoreError(f"line {lineno}: tempo {bpm} outside 10..400 bpm")
                tempo.set(position, bpm)
                tempo_given = True
            elif word == "meter":
                num, _, den = rest.partition("/")
                count, unit = float(num), den.strip()
                if not 0 < count < math.inf or not unit.isdigit() or not 0 < int(unit) <= MAX_METER_UNIT:
                    raise ValueError(rest)
                if count * 4 / int(unit) < 4 / MAX_METER_UNIT:  # bars of a few 1e-12 beats: the grid's tolerances
                    raise ValueError(rest)
                # N notes of 1/D: N x 4/D beats (quarter notes), as a MIDI file's time signature; D was ignored,
                # 6/8 bars were 6 beats, their eighths as long as quarters
                beats_per_bar = count * 4 / int(unit)
                count_unit = 4 / int(unit)
                meter = (count, f"{num.strip()}/{unit}")
            elif word == "repeat":
                count = int(rest)
                if count < 1:
                    raise ScoreError(f"line {lineno}: repeat needs a count of 1 or more, got {count}")
                if not last_block_beats:  # was "needs a count >= 1 after a grid block", whatever the count
                    raise ScoreError(f"line {lineno}: repeat {count} plays the last grid block again, and there is "
                                     f"none before it: write it after a grid block (rests and at lines are not "
                                     f"repeated)")
                if since_block is not None:  # a rest or `at` notes between: they are not played again
                    warnings.append(f"line {lineno}: repeat plays the grid block of line {last_block_line} again, "
                                    f"not the {since_block[0]} line {since_block[1]} after it (a block's own '.' "
                                    f"cells repeat with it; {FIGURES_DOC})")
                    since_block = None
                check_until(position + count * last_block_beats, len(events) + count * len(last_block), lineno)
                for _ in range(count):
                    _place(last_block, position)
                    add_bars(position, last_block_beats, last_block_bar, last_block_unit)
                    position += last_block_beats
            elif word == "grip":
                if rest.lower() in RENDER_ONLY_GRIPS:  # the renderer's --grip takes them: say so, not just "french"
                    raise ScoreError(f"line {lineno}: cannot read {line.strip()!r}: write grip "
                                     f"{DIRECTIVE_FORMS[word]}; the {rest.lower()} grip is given to the renderer: "
                                     f"batteur render --grip {rest.lower()} (or batteur evaluate --grip)")
                grip = Grip(rest.lower())
            elif word == "nuance":
                nuance = Nuance(rest.lower().replace(" ", "_"))
            elif word in ("at", "note"):
                note(lineno, rest)
                since_block = since_block or (word, lineno)
            elif word == "rest":
                since_block = since_block or (word, lineno)
                length = _finite(rest, "a rest", lineno) if rest else beats_per_bar
                if length < 0:
                    raise ScoreError(f"line {lineno}: a rest cannot be negative, got {rest}")
                check_until(position + length, len(events), lineno)
                add_bars(position, length)
                position += length
            elif word == "kit":
                if not rest:
                    raise ValueError("no kit name")
                kit_named = (rest, lineno)
            elif word == "title":
                pass
            elif _row_without_bar_lines(head, rest):  # 'HH x.x.x.x.'
                raise ScoreError(f"line {lineno}: a grid row needs its bars between '|': write "
                                 f"{head} |{rest.replace(' ', '') or 'x.x.x.x.'}|")
            else:  # the directives, and how the figure meant is written when it is a known one (swing, ...)
                hint = FIGURE_HINTS.get(word, "")
                raise ScoreError(f"line {lineno}: unknown directive {head!r}: {hint + '; ' if hint else ''}the "
                                 f"directives are {_either(DIRECTIVE_NAMES)}, and a grid row is NAME |cells| "
                                 f"({FIGURES_DOC})")
        except ScoreError:
            raise
        except (ValueError, IndexError, OverflowError) as exc:
            form = DIRECTIVE_FORMS.get(word)
            how = f": write {word} {form}" if form else f" ({exc})"
            raise ScoreError(f"line {lineno}: cannot read {line.strip()!r}{how}") from exc
    flush()
    if events and (not bar_starts or last_note > position + 1e-9):
        # `at` notes after the last block or rest (or `at` lines only: the score had no bar and a single beat):
        # bars of the meter in force from where the score ended, as a block there would start, through the one
        # holding the last note (a whole bar, as a block's), and beats at the last tempo over them; the beats
        # stopped at the last block, and the position was counted on at its tempo and in its bars
        end = position + (math.floor((last_note - position) / beats_per_bar + 1e-9) + 1) * beats_per_bar
        check_until(end, len(events), last_note_line)  # a bar of a million beats: seconds of beats to fill
        add_bars(position, end - position)
        position = end
    elif bar_starts and position - bar_starts[-1] < last_bar - 1e-9:
        # a closing rest shorter than a bar: past the end, bars of the meter in force from where it ends, as a
        # block there would start (they went on as short as the rest's bar). The second start, past the end,
        # gives them their length (common.score.position counts on from the last two).
        add_bars(position, 2 * beats_per_bar)
    if bar_starts and position != math.floor(position) and bar_starts[-1] < position:
        # a whole last bar ending between two beats (a fractional meter): the beats stop at the last whole one,
        # which would cut the bar short; a start where it ends gives it and the bars past the end their length
        # (common.score.position counts on from the last two, as past a MIDI file's end)
        add_bars(position, last_bar, last_bar, bar_units[-1])
    if not events:  # as a MIDI file's (the score plays nothing; a blank file said "0 events" only)
        warnings.append("no drum events")
    elif not tempo_given:
        warnings.insert(0, f"no tempo line: played at {DEFAULT_BPM:g} beats (quarter notes) per minute")
    # doubles strike one object with one stroke (common.score.events.double_key): crash2 and CR at once are two
    # crashes; without a kit loaded no note names an object by pitch, and the event type decides
    kept, removed = remove_duplicates(events, key=double_key(kit if kit is not None else next(iter(ids_kit), None)))
    # at least beats 0 and 1: a score shorter than a beat (one bar of 1/8) has a beat's length to count bars by
    beats = np.array([tempo.seconds(b) for b in np.arange(0.0, max(position, 1.0) + 1e-9, 1.0)])
    score = TextScore(events=kept, beats=beats, bar_beats=np.array(bar_starts, dtype=float), duplicates=removed,
                      source=source, end_beat=position, bar_units=np.array(bar_units, dtype=float))
    score.grip = grip
    score.nuance = nuance
    score.kit, score.kit_line = kit_named if kit_named is not None else (None, None)
    score.warnings = warnings
    return score


MIDI_SUFFIXES = (".mid", ".midi", ".smf", ".rmi")
"""File names read as MIDI whatever they hold (``.rmi``: RIFF MIDI)."""


def read_score(path: str | Path, kit: Kit | None = None, **kwargs: object) -> Score:
    """Read a score file: ``.mid``/``.midi``/``.smf``/``.rmi`` or a file starting as a Standard MIDI File or a RIFF
    MIDI file does as MIDI, anything else as the text format.

    Keyword arguments (``drum_channels``, ``progress``, ...) go to :func:`common.score.midi.read_midi`; a text score
    ignores them (it has no channels, and reads quickly: 208,000 notes in about 1 s, without progress reports).
    ``kit``: the kit a text score's object ids name objects of (:func:`parse_text`; None: its ``kit`` line's, else
    the default); a MIDI file's pitches choose a kit's objects by its ``note_objects`` when played, and with
    ``kit`` its doubles are those of one object (:func:`common.score.events.double_key`; without, of one event)."""
    from common.score.midi import read_midi

    p = Path(path)
    if p.suffix.lower() in MIDI_SUFFIXES:
        return read_midi(p, kit=kit, **kwargs)  # type: ignore[arg-type]
    check_file(p, str(p))
    try:
        with p.open("rb") as f:
            head = f.read(12)
    except OSError as exc:
        raise ScoreError(f"{p}: cannot read the file ({exc.strerror or exc})") from None
    if starts_as_midi(head):  # a MIDI file by another name (.kar, none): it was "not UTF-8 text"
        return read_midi(p, kit=kit, **kwargs)  # type: ignore[arg-type]
    if not head:  # as an empty MIDI file's (it read as a score of no notes)
        raise ScoreError(f"{p}: the file is empty (0 bytes)")
    text = _score_text(p, head)
    try:
        score = parse_text(text, source=str(p), kit=kit)
    except ScoreError as exc:
        raise ScoreError(f"{p}: {exc}") from exc
    score.warnings = [f"{p}: {warning}" for warning in score.warnings]  # as its errors, and a MIDI file's warnings
    unused = [option for key, option in MIDI_ONLY.items() if kwargs.get(key) not in (None, False)]
    if unused:  # given for this file, they did nothing: said once (until 7 Dec not a word)
        score.warnings.append(f"{p}: {' and '.join(unused)} not used: a text score names its drums (they read "
                              "MIDI files)")
    return score


MIDI_ONLY = {"drum_channels": "--drum-channels", "note_map": "--drum-map", "hihat_cc4": "--hihat-cc4"}
""":func:`read_score`'s keyword arguments a text score has no use for, and their options."""


def _score_text(path: Path, head: bytes) -> str:
    """The text of a score file whose first bytes are ``head``: UTF-8, or UTF-16 or UTF-32 after a byte order mark
    (Windows Notepad's "Unicode"), read before the audio formats are looked for (UTF-16's mark FF FE made it "an
    audio file (MP3)"). :class:`ScoreError` if it cannot be read or is not text."""
    bom = unicode_bom(head)
    try:
        return read_text(path) if bom is None else path.read_bytes().decode(bom[0])
    except OSError as exc:
        raise ScoreError(f"{path}: cannot read the file ({exc.strerror or exc})") from None
    except UnicodeDecodeError as exc:  # a byte order mark, then no such text
        name = bom[1] if bom is not None else "UTF-8"
        raise ScoreError(f"{path}: not a text score (it starts as {name} text but is not: {exc.reason} at byte "
                         f"{exc.start}); save it as UTF-8") from None
    except ValueError as exc:  # not UTF-8: a binary file (an audio file given as the score?)
        check_not_audio(head, str(path))
        raise ScoreError(f"{path}: not a text score ({exc})") from None


DEFAULT_KIT = "default"
"""The kit a score plays when neither the command line nor the score names one."""


def score_kit(score: Score | None) -> str | None:
    """The kit ``score`` asks for (a text score's ``kit`` line; None: none): a shipped kit's name, or a kit file's
    path, taken from the score's folder when relative (where a score and its kit are kept together)."""
    name = getattr(score, "kit", None)
    if not isinstance(name, str):
        return None
    path = Path(name)
    if not path.suffix or path.is_absolute() or score is None or not score.source:
        return name  # a shipped kit's name (load_kit: a name has no suffix), or a path as written
    return str(Path(score.source).parent / path)


def load_score_kit(score: Score | None, given: str | None, where: str | Path | None = None,
                   load: Callable[[str], Kit] = load_kit) -> Kit:
    """The kit ``score`` plays, loaded with ``load`` (:func:`common.kit.load_kit`, or one given a drummer's height
    and limbs): ``given`` (a ``--kit`` option) unless None, else the score's ``kit`` line (:func:`score_kit`),
    else :data:`DEFAULT_KIT`; one place for every command that reads scores (render, evaluate, ``python -m
    common.score``). A kit the score's line names that cannot be loaded is a :class:`ScoreError` naming the line
    (``WHERE: line 2: kit 'x': why``; ``where``: the score's file unless given); ``given``'s raises what
    ``load_kit`` raises (``FileNotFoundError``, ``ValueError``)."""
    name = given or score_kit(score) or DEFAULT_KIT
    try:
        return load(name)
    except (FileNotFoundError, ValueError) as exc:
        line = getattr(score, "kit_line", None)
        if given is not None or score is None or line is None:
            raise
        raise ScoreError(f"{where if where is not None else score.source}: line {line}: kit "
                         f"{getattr(score, 'kit', name)!r}: {exc}") from None
