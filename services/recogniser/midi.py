"""Writing recognised drum events as a General MIDI drum Standard MIDI File (channel 10)."""

from __future__ import annotations

import io
import math
from collections.abc import Sequence
from pathlib import Path

import mido

from common.output_paths import write_atomically
from services.recogniser.transcribe import DrumEvent

DRUM_CHANNEL = 9
"""MIDI channel 10 (0-based index 9): General MIDI percussion."""


TEMPO_RANGE_BPM = (10.0, 1000.0)
"""Tempos the MIDI file may carry, BPM (a grid for score editors; times are exact at any of them)."""


TICKS_PER_BEAT = 480
"""Ticks per beat at 120 BPM and above (a tick of 1/960 s or less); slower tempos get a multiple of it."""


def ticks_per_beat_for(tempo_bpm: float) -> int:
    """Ticks per beat keeping a tick at most 1/960 s at any tempo (at 480 per beat a 10 BPM tick would be
    12.5 ms, moving strikes by up to 6 ms: a flam's width)."""
    return TICKS_PER_BEAT * max(1, math.ceil(120.0 / tempo_bpm - 1e-9))


def events_to_midi(
    events: Sequence[DrumEvent], tempo_bpm: float = 120.0, ticks_per_beat: int | None = None,
    note_length_s: float = 0.05,
) -> mido.MidiFile:
    """A type-1 MIDI file with one drum track holding the events.

    Times are kept exactly (up to one tick, at most 1/960 s: :func:`ticks_per_beat_for` unless
    ``ticks_per_beat`` is given); the tempo only sets the grid a score editor shows. Each note lasts
    ``note_length_s`` or until the next strike of the same note.
    """
    if not TEMPO_RANGE_BPM[0] <= tempo_bpm <= TEMPO_RANGE_BPM[1]:
        raise ValueError(f"tempo {tempo_bpm} BPM is outside {TEMPO_RANGE_BPM[0]}..{TEMPO_RANGE_BPM[1]}")
    ticks_per_beat = ticks_per_beat or ticks_per_beat_for(tempo_bpm)
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
    """Write the events to ``path`` as a Standard MIDI File; returns the path.

    Written whole or not at all (:func:`common.output_paths.write_atomically`): a failed write (a full disk)
    leaves neither a partial file nor a damaged earlier one.
    """
    p = Path(path)
    data = io.BytesIO()
    events_to_midi(events, tempo_bpm=tempo_bpm).save(file=data)
    write_atomically(p, data.getvalue())
    return p
