"""The drum classes the recogniser tells apart and their General MIDI notes.

Nine classes, the reduction of the Groove MIDI Dataset paper (Gillick et al. 2019),
each mapped to one General MIDI drum note (written to channel 10) and to one of
the 15 drum event types of Kragtwijk et al. (2001) (:class:`common.kit.EventType`).
"""

from __future__ import annotations

from dataclasses import dataclass

from common.kit import EventType


@dataclass(frozen=True)
class DrumClass:
    """One recognised drum class.

    ``note`` is the General MIDI drum note written for it; ``groove_pitches`` are
    the MIDI pitches of the Groove MIDI Dataset (Roland TD-11) folded into it.
    """

    name: str
    note: int
    event_type: EventType
    groove_pitches: tuple[int, ...]


CLASSES: tuple[DrumClass, ...] = (
    DrumClass("kick", 36, EventType.BASS, (35, 36)),
    DrumClass("snare", 38, EventType.SNARE, (37, 38, 40)),
    DrumClass("hihat_closed", 42, EventType.HIHATCLOSED, (22, 42, 44)),
    DrumClass("hihat_open", 46, EventType.HIHATOPEN, (26, 46)),
    DrumClass("tom_high", 48, EventType.HIGHTOM, (48, 50)),
    DrumClass("tom_mid", 45, EventType.MIDTOM, (45, 47)),
    DrumClass("tom_floor", 43, EventType.FLOORTOM, (41, 43, 58)),
    DrumClass("crash", 49, EventType.CRASH, (49, 52, 55, 57)),
    DrumClass("ride", 51, EventType.RIDE, (51, 53, 59)),
)
"""The classes, in the order of the model's outputs."""

CLASS_NAMES: tuple[str, ...] = tuple(c.name for c in CLASSES)
N_CLASSES = len(CLASSES)

_PITCH_TO_CLASS = {p: i for i, c in enumerate(CLASSES) for p in c.groove_pitches}
_NOTE_TO_CLASS = {c.note: i for i, c in enumerate(CLASSES)}


def class_of_pitch(pitch: int) -> int | None:
    """Class index of a Groove / General MIDI drum pitch, or None if it is none of the nine."""
    return _PITCH_TO_CLASS.get(pitch)


def class_of_note(note: int) -> int | None:
    """Class index of a note the recogniser writes (or any pitch folded into a class)."""
    return _NOTE_TO_CLASS.get(note, _PITCH_TO_CLASS.get(note))
