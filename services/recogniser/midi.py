"""Writing recognised drum events as a General MIDI drum Standard MIDI File (channel 10)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import mido

from services.recogniser.transcribe import DrumEvent

DRUM_CHANNEL = 9
"""MIDI channel 10 (0-based index 9): General MIDI percussion."""


TEMPO_RANGE_BPM = (10.0, 1000.0)
"""Tempos the MIDI file may carry, BPM (a grid for score editors; times are exact at any of them)."""


def events_to_midi(
    events: Sequence[DrumEvent], tempo_bpm: float = 120.0, ticks_per_beat: int = 480, note_length_s: float = 0.05
) -> mido.MidiFile:
    """A type-1 MIDI file with one drum track holding the events.

    Times are kept exactly (up to one tick: 1/960 s at the default 120 BPM); the
    tempo only sets the grid a score editor shows. Each note lasts ``note_length_s``
    or until the next strike of the same note.
    """
    if not TEMPO_RANGE_BPM[0] <= tempo_bpm <= TEMPO_RANGE_BPM[1]:
        raise ValueError(f"tempo {tempo_bpm} BPM is outside {TEMPO_RANGE_BPM[0]}..{TEMPO_RANGE_BPM[1]}")
    tempo = mido.bpm2tempo(tempo_bpm)
    sec_per_tick = tempo / 1e6 / ticks_per_beat

    def tick(t: float) -> int:
        return max(0, int(round(t / sec_per_tick)))

    timeline: list[tuple[int, int, mido.Message]] = []
    by_note: dict[int, list[DrumEvent]] = {}
    for e in sorted(events, key=lambda e: e.time):
        by_note.setdefault(e.note, []).append(e)
    for note, evs in by_note.items():
        for i, e in enumerate(evs):
            on = tick(e.time)
            off = tick(e.time + note_length_s)
            if i + 1 < len(evs):
                off = min(off, tick(evs[i + 1].time))
            off = max(off, on + 1)
            timeline.append((on, 1, mido.Message("note_on", channel=DRUM_CHANNEL, note=note, velocity=e.velocity)))
            timeline.append((off, 0, mido.Message("note_off", channel=DRUM_CHANNEL, note=note, velocity=0)))
    timeline.sort(key=lambda x: (x[0], x[1], x[2].note))
    track = mido.MidiTrack()
    track.append(mido.MetaMessage("track_name", name="Batteur transcription", time=0))
    track.append(mido.MetaMessage("set_tempo", tempo=tempo, time=0))
    track.append(mido.MetaMessage("time_signature", numerator=4, denominator=4, time=0))
    now = 0
    for t, _, msg in timeline:
        track.append(msg.copy(time=t - now))
        now = t
    track.append(mido.MetaMessage("end_of_track", time=0))
    mid = mido.MidiFile(type=1, ticks_per_beat=ticks_per_beat)
    mid.tracks.append(track)
    return mid


def write_midi(events: Sequence[DrumEvent], path: str | Path, tempo_bpm: float = 120.0) -> Path:
    """Write the events to ``path`` as a Standard MIDI File; returns the path."""
    p = Path(path)
    events_to_midi(events, tempo_bpm=tempo_bpm).save(str(p))
    return p
