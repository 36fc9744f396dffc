"""Live notes over OSC (:class:`common.messages.score.LiveNote`) -> drum events."""

from __future__ import annotations

from collections.abc import Mapping

from common.kit import EventType
from common.messages.score import LiveNote
from common.score.events import DrumEvent, UnknownNote
from common.score.gm import DRUM_MAP


class LiveNotes:
    """Turns live notes into drum events; counts unknown pitches (never raises).

    ``velocity`` 0 notes are note-offs and are ignored. Events come out in
    arrival order; a note of the same type within ``duplicate_window`` seconds of
    the previous one is a double event and is dropped (counted).

    ``note_map``: the sender's pitch -> the General MIDI drum pitch it plays (``--drum-map``'s map,
    :func:`common.score.midi_notes.load_drum_map`), applied first, as the MIDI reader applies it to a file: the
    event carries the General MIDI pitch (a kit's ``note_objects`` choose by it), an unknown note the pitch sent.
    None or empty: the pitches are General MIDI's (until the day after 7 Dec live notes always were, whatever the
    node's ``--drum-map``)."""

    def __init__(self, drum_map: Mapping[int, EventType] = DRUM_MAP, duplicate_window: float = 0.010,
                 note_map: Mapping[int, int] | None = None) -> None:
        self.drum_map = drum_map
        self.duplicate_window = duplicate_window
        self.note_map: Mapping[int, int] = dict(note_map or {})
        self.unknown: list[UnknownNote] = []
        self.duplicates = 0
        self._last: dict[EventType, float] = {}

    def accept(self, note: LiveNote) -> DrumEvent | None:
        """The drum event of a live note, or None (note-off, unknown pitch or double event)."""
        if note.velocity == 0:
            return None
        pitch = self.note_map.get(note.pitch, note.pitch)
        event = self.drum_map.get(pitch)
        velocity = note.velocity / 127.0
        if event is None:
            self.unknown.append(UnknownNote(note.time, note.pitch, velocity, note.channel))
            return None
        last = self._last.get(event)
        if last is not None and abs(note.time - last) < self.duplicate_window:
            self.duplicates += 1
            return None
        self._last[event] = note.time
        return DrumEvent(time=note.time, event=event, velocity=velocity, pitch=pitch)
