"""Small MIDI files built with mido for the score reader's tests."""

from __future__ import annotations

import io
import struct

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


KEY_C = b"\xff\x59\x02\x00\x00"
"""A key signature meta message of C major, as mido writes it."""


def with_key(data: bytes, key: bytes) -> bytes:
    """``data`` (one track, made with ``drum_midi(..., key=True)``) with its key signature of C replaced by the meta
    message bytes ``key`` (e.g. ``b"\\xff\\x59\\x02\\xee\\x01"``: 18 flats, which mido refuses)."""
    assert data.count(KEY_C) == 1 and data.count(b"MTrk") == 1
    track = data.index(b"MTrk")
    size = struct.unpack(">I", data[track + 4 : track + 8])[0] + len(key) - len(KEY_C)
    body = data[track + 8 :].replace(KEY_C, key)
    return data[:track] + b"MTrk" + struct.pack(">I", size) + body


def riff_chunk(name: bytes, body: bytes) -> bytes:
    """A RIFF chunk: little-endian size, padded to an even length."""
    return name + struct.pack("<I", len(body)) + body + b"\x00" * (len(body) % 2)


def riff_midi(smf: bytes, before: bytes = b"", form: bytes = b"RMID") -> bytes:
    """A RIFF MIDI file (``.rmi``) wrapping the Standard MIDI File ``smf`` in its ``data`` chunk, ``before`` (other
    chunks) ahead of it."""
    body = form + before + riff_chunk(b"data", smf)
    return b"RIFF" + struct.pack("<I", len(body)) + body
