"""How a MIDI file's notes become General MIDI drum pitches before :data:`common.score.gm.DRUM_MAP` gives them
their drum event types: a note map for a file not laid out as General MIDI (``--drum-map``), and the hi-hat's
openness a file sends as its foot controller (CC4).

A note map is a small JSON or TOML file, each entry a pitch of the file and what it plays: a General MIDI drum
pitch (35-81, or the TD-11's 22 and 26) or a drum event type's name (``HIHATCLOSED``)::

    {"description": "EZdrummer-style hats", "notes": {"25": 42, "60": "HIHATOPEN", "3": "HIHATPEDAL"}}

    description = "EZdrummer-style hats"
    [notes]
    25 = 42
    60 = "HIHATOPEN"

Pitches it does not list are read as General MIDI. A shipped map is chosen by name (:data:`SHIPPED_MAPS`:
``roland-td``). docs/score-format.md ("Note maps") says the same for users.
"""

from __future__ import annotations

import difflib
import json
import tomllib
from collections.abc import Collection
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from common.kit import EventType
from common.score.gm import DRUM_MAP, EVENT_PITCHES

NoteMap = dict[int, int]
"""A file's MIDI pitch -> the General MIDI drum pitch it plays (a key of :data:`common.score.gm.DRUM_MAP`)."""

ROLAND_TD: NoteMap = {
    36: 36,  # kick
    38: 38, 40: 40, 37: 37,  # snare head, rim (rimshot), cross stick
    48: 48, 50: 50,  # tom 1 head, rim
    45: 45, 47: 47,  # tom 2 head, rim
    43: 43, 58: 43,  # tom 3 head, rim (General MIDI's 58 is a vibraslap)
    46: 46, 26: 26, 42: 42, 22: 22, 44: 44,  # hi-hat open bow, open edge, closed bow, closed edge, pedal
    49: 49, 55: 49,  # crash 1 bow, edge (General MIDI's 55 is a splash)
    57: 57, 52: 57,  # crash 2 bow, edge (General MIDI's 52 is a china)
    51: 51, 59: 51, 53: 53,  # ride bow, edge (General MIDI's 59 is a second ride), bell
}
"""The default note assignments of Roland's TD-series modules (TD-11, TD-17, TD-27...; the Groove MIDI Dataset's
table for its TD-11): the edges of the hi-hat stay the TD-11's 22 and 26 (:data:`common.score.gm.DRUM_MAP`), the
rims of toms 1 and 2 are General MIDI's toms of the same type, tom 3's rim, the crash edges and the ride's edge
become the pad's head or bow."""

SHIPPED_MAPS: dict[str, NoteMap] = {"roland-td": ROLAND_TD}
"""Note maps chosen by name (``--drum-map roland-td``)."""

MAP_SUFFIXES = (".json", ".toml")
MAX_MAP_BYTES = 1 << 20
"""The largest note map file read (a map of all 128 pitches is some 2 kB)."""


class DrumMapError(ValueError):
    """A note map that cannot be used; the message names the map (and the entry) and the problem."""


def map_target(value: Any) -> int:
    """The General MIDI drum pitch a note map's entry plays: a pitch of :data:`DRUM_MAP` (an integer, or its digits
    as a string) or an event type's name, any case (:data:`common.score.gm.EVENT_PITCHES`); ValueError otherwise."""
    if isinstance(value, str) and value.strip().isdigit():
        value = int(value)
    if isinstance(value, int) and not isinstance(value, bool):
        if value in DRUM_MAP:
            return value
        raise ValueError(f"{value} is not a drum pitch Batteur plays (General MIDI's 35 to 81, or the TD-11's 22 "
                         "and 26)")
    if isinstance(value, str) and value.strip().upper() in EventType.__members__:
        return EVENT_PITCHES[EventType[value.strip().upper()]]
    raise ValueError(f"{value!r} is neither a General MIDI drum pitch (35 to 81, 22, 26) nor a drum event type "
                     f"({', '.join(EventType)})")


def map_pitch(key: Any) -> int:
    """A note map's key: a MIDI pitch, 0 to 127 (JSON and TOML keys are strings); ValueError otherwise."""
    text = str(key).strip()
    if not text.isdigit() or int(text) > 127:
        raise ValueError(f"{str(key)!r} is not a MIDI pitch (0 to 127)")
    return int(text)


class DrumMapFile(BaseModel):
    """A note map file: ``notes`` (a pitch of the file -> a General MIDI drum pitch or an event type's name) and an
    optional ``description``."""

    model_config = ConfigDict(extra="forbid")

    description: str = Field("", description="what the map is for (not used)")
    notes: dict[str, Any] = Field(min_length=1, description="MIDI pitch (0-127) -> GM drum pitch or event type")

    @field_validator("notes")
    @classmethod
    def _entries(cls, notes: dict[str, Any]) -> dict[str, Any]:
        problems = []
        for key, value in notes.items():
            try:
                map_pitch(key)
                map_target(value)
            except ValueError as exc:
                problems.append(f"entry {key}: {exc}")
        if problems:
            raise ValueError("; ".join(problems))
        return notes

    def note_map(self) -> NoteMap:
        """The map's entries as pitches (validated)."""
        return {map_pitch(key): map_target(value) for key, value in self.notes.items()}


def load_drum_map(spec: str) -> NoteMap:
    """The note map ``--drum-map`` names: a shipped map's name (:data:`SHIPPED_MAPS`) or a ``.json``/``.toml``
    file's path; :class:`DrumMapError` naming the map, and the entry, for one it cannot use."""
    if spec in SHIPPED_MAPS:
        return dict(SHIPPED_MAPS[spec])
    path = Path(spec)
    shipped = ", ".join(SHIPPED_MAPS)
    if not path.is_file() and spec.strip().lower() in SHIPPED_MAPS:  # ROLAND-TD: a name, any case (not a file)
        return dict(SHIPPED_MAPS[spec.strip().lower()])
    if not path.is_file():
        why = "is a folder" if path.is_dir() else "does not exist"
        near = difflib.get_close_matches(spec.strip().lower(), SHIPPED_MAPS, n=1, cutoff=0.5)
        hint = f" (did you mean {near[0]}?)" if near and not path.is_dir() else ""
        raise DrumMapError(f"{spec}: {why}{hint}; give a note map file (.json or .toml) or a shipped map's name "
                           f"({shipped})")
    if path.suffix.lower() not in MAP_SUFFIXES:
        raise DrumMapError(f"{spec}: a note map is a .json or .toml file")
    try:
        if path.stat().st_size > MAX_MAP_BYTES:
            raise DrumMapError(f"{spec}: too large for a note map (at most {MAX_MAP_BYTES // 1024} kB)")
        text = path.read_text(encoding="utf-8-sig")
    except OSError as exc:
        raise DrumMapError(f"{spec}: cannot read the file ({exc.strerror or exc})") from None
    except UnicodeDecodeError:
        raise DrumMapError(f"{spec}: not UTF-8 text") from None
    try:
        data = tomllib.loads(text) if path.suffix.lower() == ".toml" else json.loads(text)
    except (tomllib.TOMLDecodeError, json.JSONDecodeError) as exc:
        raise DrumMapError(f"{spec}: not valid {path.suffix[1:].upper()} ({exc})") from None
    if not isinstance(data, dict):
        raise DrumMapError(f"{spec}: a note map is an object with a \"notes\" table of pitch: drum entries")
    try:
        return DrumMapFile.model_validate(data).note_map()
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(part) for part in first["loc"])
        message = str(first["msg"]).removeprefix("Value error, ")
        if first["type"] == "too_short" and first["loc"] == ("notes",):  # not pydantic's "at least 1 item"
            message = 'the map has no notes (give pitch: drum entries, e.g. "notes": {"25": 42})'
        raise DrumMapError(f"{spec}: {where}: {message}") from None


HIHAT_OPEN_MAX_CC4 = 31
"""CC4 (the hi-hat pedal: 0 up, fully open .. 127 down, closed) at or below which a closed hi-hat note is played
open: the pedal clearly up (openness at least 3/4). Roland's TD-11 sends 0 to 90; its notes already say open or
closed, and a closed note never came with less than 48 in the Groove MIDI Dataset's files in tests/data."""
HIHAT_CLOSED_MIN_CC4 = 96
"""CC4 at or above which an open hi-hat note is played closed: the pedal clearly down (openness at most 1/4).
The TD-11's fully closed is 90, so its open notes (some sent with 90: the pedal closed after the stroke) stay
open. Between the two the hat is half open: played as its note says (a score has no half-open hi-hat)."""

OPENED = {42: 46, 22: 26}
"""Closed hi-hat bow and edge pitches -> the open ones, the same stroke with the pedal up."""
CLOSED = {open_: closed for closed, open_ in OPENED.items()}
"""Open hi-hat bow and edge pitches -> the closed ones."""


class HiHatPedal:
    """The hi-hat pedal a MIDI file sends as CC4 (foot controller), per channel, applied to its hi-hat notes with
    ``--hihat-cc4`` (off by default: a Roland TD-11 chooses open or closed notes itself and sends closed ones with
    CC4 anywhere from 0 to 90, so 95 of the Groove MIDI Dataset's 1,021 files read differently with it): a
    closed note (42, 22) with the pedal clearly up is played open, an open one (46, 26) with the pedal clearly down
    closed (:data:`HIHAT_OPEN_MAX_CC4`, :data:`HIHAT_CLOSED_MIN_CC4`). Before a channel's first CC4 its notes are
    played as they are. Notes it changed are remembered (time, channel, new pitch) for :meth:`notice`."""

    def __init__(self) -> None:
        self.cc4: dict[int, int] = {}
        self.changed: set[tuple[float, int, int]] = set()
        self.would_move: set[tuple[float, int, int]] = set()  # notes it would change, as written: unused_notice

    def control(self, channel: int, value: int) -> None:
        """A CC4 message on ``channel`` (0-based), ``value`` 0-127."""
        self.cc4[channel] = value

    def pitch(self, seconds: float, channel: int, pitch: int, apply: bool = True) -> int:
        """The General MIDI pitch a note of ``pitch`` (a GM drum pitch: the note map applied) on ``channel`` plays
        with the pedal as it is; ``pitch`` itself when not ``apply`` (``--hihat-cc4`` not given: the note is
        remembered for :meth:`unused_notice` if the pedal would change it)."""
        value = self.cc4.get(channel)
        if value is None:
            return pitch
        played = pitch
        if value <= HIHAT_OPEN_MAX_CC4:
            played = OPENED.get(pitch, pitch)
        elif value >= HIHAT_CLOSED_MIN_CC4:
            played = CLOSED.get(pitch, pitch)
        if played == pitch:
            return pitch
        if not apply:
            self.would_move.add((seconds, channel, pitch))
            return pitch
        self.changed.add((seconds, channel, played))
        return played

    def unused_notice(self, notes: Collection[tuple[float, int, int]], name: str) -> str | None:
        """Without ``--hihat-cc4`` (the pedal followed, not applied): that ``notes`` (time, 0-based channel, pitch:
        the notes read as drums) have hi-hat notes the pedal would open or close and how to apply it, or None. None
        too when their hi-hat notes say both open and closed: the sender chose them with its pedal (a Roland TD-11
        sends closed notes with CC4 anywhere from 0 to 90): 17 of the Groove MIDI Dataset's 1,021 files are told
        of it (fills of closed or open hats only), not the 95 the option changes."""
        hats = [pitch for _, _, pitch in notes if pitch in OPENED or pitch in CLOSED]
        moved = sum(n in self.would_move for n in notes)
        closed = sum(pitch in OPENED for pitch in hats)
        if not moved or 0 < closed < len(hats):
            return None
        return (f"{name}: sends the hi-hat pedal (CC4), not applied: {moved} of its {len(hats)} "
                f"{'closed' if closed else 'open'} hi-hat notes would play {'open' if closed else 'closed'} with "
                f"--hihat-cc4 (a closed note with CC4 at most {HIHAT_OPEN_MAX_CC4}, the pedal up, plays open; an "
                f"open one with at least {HIHAT_CLOSED_MIN_CC4} closed)")

    def notice(self, notes: Collection[tuple[float, int, int]], name: str) -> str | None:
        """What the pedal changed among ``notes`` (time, 0-based channel, pitch: the notes read as drums), or None."""
        changed = [n for n in notes if n in self.changed]
        if not changed:
            return None
        opened = sum(pitch in CLOSED for _, _, pitch in changed)
        closed = len(changed) - opened
        parts = ([f"{opened} closed hi-hat note{'s' * (opened != 1)} played open (CC4 at most "
                  f"{HIHAT_OPEN_MAX_CC4}: the pedal up)"] if opened else []) + (
                 [f"{closed} open hi-hat note{'s' * (closed != 1)} played closed (CC4 at least "
                  f"{HIHAT_CLOSED_MIN_CC4}: the pedal down)"] if closed else [])
        return f"{name}: hi-hat pedal (CC4): {', '.join(parts)}"


def note_map_json(note_map: NoteMap | None) -> dict[str, int] | None:
    """A note map as report.json holds it (``drum_map``: ``{"25": 42}``, pitches as JSON keys), None without one:
    ``batteur evaluate`` reads a render directory's score with it, as it was played."""
    return None if note_map is None else {str(pitch): gm for pitch, gm in sorted(note_map.items())}


def note_map_from_json(value: Any, where: str) -> NoteMap | None:
    """The note map report.json's ``drum_map`` holds (:func:`note_map_json`), None for none;
    :class:`DrumMapError` naming ``where`` for one that is not a map."""
    if value is None:
        return None
    try:
        return DrumMapFile.model_validate({"notes": value}).note_map()
    except ValidationError as exc:
        message = str(exc.errors()[0]["msg"]).removeprefix("Value error, ")
        raise DrumMapError(f"{where}: drum_map is not a note map ({message})") from None
