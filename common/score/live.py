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
    """

    def __init__(self, drum_map: Mapping[int, EventType] = DRUM_MAP, duplicate_window: float = 0.010) -> None:
        self.drum_map = drum_map
        self.duplicate_window = duplicate_window
        self.unknown: list[UnknownNote] = []
        self.duplicates = 0
        self._last: dict[EventType, float] = {}

    def accept(self, note: LiveNote) -> DrumEvent | None:
        """The drum event of a live note, or None (note-off, unknown pitch or double event)."""
        if note.velocity == 0:
            return None
        event = self.drum_map.get(note.pitch)
        velocity = note.velocity / 127.0
        if event is None:
            self.unknown.append(UnknownNote(note.time, note.pitch, velocity, note.channel))
            return None
        last = self._last.get(event)
        if last is not None and abs(note.time - last) < self.duplicate_window:
            self.duplicates += 1
            return None
        self._last[event] = note.time
        return DrumEvent(time=note.time, event=event, velocity=velocity, pitch=note.pitch)
