"""Live notes over OSC (:class:`common.messages.score.LiveNote`) -> drum events."""

from __future__ import annotations

from collections.abc import Callable, Hashable, Mapping

from common.kit import EventType, Kit
from common.messages.score import LiveNote
from common.score.events import DrumEvent, UnknownNote, double_key
from common.score.gm import DRUM_MAP


class LiveNotes:
    """Turns live notes into drum events; counts unknown pitches (never raises).

    ``velocity`` 0 notes are note-offs and are ignored. Events come out in
    arrival order; a note of the same type within ``duplicate_window`` seconds of
    the previous one is a double event and is dropped (counted).

    ``note_map``: the sender's pitch -> the General MIDI drum pitch it plays (``--drum-map``'s map,
    :func:`common.score.midi_notes.load_drum_map`), applied first, as the MIDI reader applies it to a file: the
    event carries the General MIDI pitch (a kit's ``note_objects`` choose by it), an unknown note the pitch sent.
    None or empty: the pitches are General MIDI's (until 7 Dec live notes always were, whatever the
    node's ``--drum-map``).

    ``kit``: the kit the notes are played on: doubles are then two notes striking one object with one stroke, as a
    score's (:func:`common.score.events.double_key`: 49 and 57 at once are two crashes on a kit sending 57 to
    ``crash2``); None: two notes of one event type (as until 7 Dec)."""

    def __init__(self, drum_map: Mapping[int, EventType] = DRUM_MAP, duplicate_window: float = 0.010,
                 note_map: Mapping[int, int] | None = None, kit: Kit | None = None) -> None:
        self.drum_map = drum_map
        self.duplicate_window = duplicate_window
        self.note_map: Mapping[int, int] = dict(note_map or {})
        self.unknown: list[UnknownNote] = []
        self.duplicates = 0
        self._last: dict[Hashable, float] = {}
        self._key: Callable[[DrumEvent], Hashable] | None = None
        self.kit = kit

    @property
    def kit(self) -> Kit | None:
        """The kit whose objects tell doubles apart (None: event types do)."""
        return self._kit

    @kit.setter
    def kit(self, kit: Kit | None) -> None:
        self._kit = kit
        self._key = double_key(kit)

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
        drum = DrumEvent(time=note.time, event=event, velocity=velocity, pitch=pitch)
        key = event if self._key is None else self._key(drum)
        last = self._last.get(key)
        if last is not None and abs(note.time - last) < self.duplicate_window:
            self.duplicates += 1
            return None
        self._last[key] = note.time
        return drum
