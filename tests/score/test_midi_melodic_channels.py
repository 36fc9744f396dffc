"""A MIDI file with no notes on a drum channel is read as drums with a warning; the warning names the General MIDI
program each such channel set (``reading channels [3] (Violin) as drums``): a melody file read as drums says so."""

from __future__ import annotations

import io

import mido
import pytest

from common.score.gm_programs import GM_PROGRAM_NAMES
from common.score.midi import CHOOSE_CHANNELS, read_midi


def _file(messages: list[mido.Message]) -> bytes:
    """A type 0 file of ``messages`` one tick apart (note-ons of 1-tick notes)."""
    track = mido.MidiTrack()
    for message in messages:
        track.append(message.copy(time=1))
        if message.type == "note_on":
            track.append(mido.Message("note_off", note=message.note, channel=message.channel, time=1))
    mid = mido.MidiFile(type=0, ticks_per_beat=480)
    mid.tracks.append(track)
    buf = io.BytesIO()
    mid.save(file=buf)
    return buf.getvalue()


def note(channel: int, pitch: int = 38) -> mido.Message:
    return mido.Message("note_on", note=pitch, velocity=100, channel=channel)


def program(channel: int, number: int) -> mido.Message:
    return mido.Message("program_change", program=number, channel=channel)


def fallback_warning(data: bytes) -> str:
    score = read_midi(data)
    [warning] = [w for w in score.warnings if "no notes on a drum channel" in w]
    said, choose = warning.split("; ", 1)[1].rsplit("; ", 1)
    assert choose == CHOOSE_CHANNELS  # every such warning says how to choose
    return said


@pytest.mark.parametrize(("messages", "says"), [
    ([program(2, 40), note(2)],
     "reading channels [3] (Violin) as drums; every channel with notes set a melodic program"),
    ([note(0)], "reading channels [1] as drums"),  # no program change: nothing to name
    ([program(2, 40), note(2), program(2, 73), note(2), program(2, 40)],
     "reading channels [3] (Violin, Flute) as drums; every channel with notes set a melodic program"),
    # until 7 Dec every channel was read, the piano's and the flute's notes played as drums
    ([program(0, 0), note(0), note(2), program(4, 73), note(4)],
     "reading channels [3] as drums; skipped channel 1 (1 note, Acoustic Grand Piano); channel 5 (1 note, "
     "Flute): a melodic program"),
    ([program(2, 40), note(2), program(4, 118), note(4), note(5)],  # Synth Drum: percussive, read
     "reading channels [5, 6] as drums: channel 5 (1 note, Synth Drum); channel 6 (1 note); skipped channel 3 "
     "(1 note, Violin): a melodic program"),
    ([program(3, 56), note(2)], "reading channels [3] as drums"),  # a program on a channel without notes
])
def test_the_warning_names_each_channels_program(messages: list[mido.Message], says: str) -> None:
    assert fallback_warning(_file(messages)) == says


def test_the_table_is_general_midis_128_programs() -> None:
    assert len(GM_PROGRAM_NAMES) == 128 == len(set(GM_PROGRAM_NAMES))
    assert (GM_PROGRAM_NAMES[0], GM_PROGRAM_NAMES[40], GM_PROGRAM_NAMES[118], GM_PROGRAM_NAMES[127]) == (
        "Acoustic Grand Piano", "Violin", "Synth Drum", "Gunshot")
