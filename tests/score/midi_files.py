"""Small MIDI files built with mido for the score reader's tests."""

from __future__ import annotations

import io

import mido


def drum_midi(signatures: list[tuple[int, int, int]], notes: list[int], key: bool = False, tpb: int = 480,
              note: int = 38) -> bytes:
    """One drum track at 120 bpm: (tick, numerator, denominator) time signatures, a drum ``note`` (the snare by
    default) at each tick of ``notes`` (the file ends at the last one), and a key signature of C at tick 0 when
    ``key``."""
    mid = mido.MidiFile(ticks_per_beat=tpb)
    track = mido.MidiTrack()
    mid.tracks.append(track)
    events: list[tuple[int, mido.Message | mido.MetaMessage]] = [
        (t, mido.MetaMessage("time_signature", numerator=n, denominator=d)) for t, n, d in signatures]
    if key:
        events.append((0, mido.MetaMessage("key_signature", key="C")))
    events += [(t, mido.Message("note_on", channel=9, note=note, velocity=100)) for t in notes]
    last = 0
    for tick, msg in sorted(events, key=lambda e: e[0]):
        track.append(msg.copy(time=tick - last))
        last = tick
    data = io.BytesIO()
    mid.save(file=data)
    return data.getvalue()
