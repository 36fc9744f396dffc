"""A MIDI file with no notes on a drum channel is read as drums with a warning; the warning names the General MIDI
program each such channel set (``channel 5 (1 note, Synth Drum)``). A file whose every channel with notes set a
melodic program holds no drums: refused, naming the programs and the option that reads it anyway."""

from __future__ import annotations

import io

import mido
import pytest

from common.score.events import ScoreError
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
    ([note(0)], "reading channels [1] as drums"),  # no program change: nothing to name
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


@pytest.mark.parametrize(("messages", "says"), [
    ([program(2, 40), note(2)], "channel 3 (1 note, Violin), set to a melodic program; to read it as drums anyway: "
                                "--drum-channels 3"),
    ([program(2, 40), note(2), program(2, 73), note(2), program(2, 40)],
     "channel 3 (2 notes, Violin, Flute), set to a melodic program; to read it as drums anyway: --drum-channels 3"),
    ([program(0, 33), note(0, 40), program(4, 0), note(4, 60)],
     "channel 1 (1 note, Electric Bass (finger)); channel 5 (1 note, Acoustic Grand Piano), set to a melodic program; "
     "to read them as drums anyway: --drum-channels 1,5"),
])
def test_a_file_of_melodic_channels_only_is_refused_with_the_option_that_reads_it(messages: list[mido.Message],
                                                                                  says: str) -> None:
    """Until 8 Dec it was read as drums with a warning: a bass line played on the snare."""
    with pytest.raises(ScoreError) as refused:
        read_midi(_file(messages))
    assert str(refused.value) == ("<bytes>: no drums: no notes on a drum channel (10, or one set to a drum bank), "
                                  f"and the notes are on {says}")
    forced = read_midi(_file(messages), drum_channels=[int(c) for c in says.rsplit(" ", 1)[1].split(",")])
    read = len(forced.events) + len(forced.unknown) + len(forced.duplicates)  # two snares 2 ticks apart: a double
    assert read == sum(m.type == "note_on" for m in messages)


def test_a_drum_file_on_channel_1_without_a_program_change_is_still_read_with_the_warning() -> None:
    score = read_midi(_file([note(0, 36), note(0, 38), note(0, 42)]))
    assert len(score.events) == 3
    [said] = [w for w in score.warnings if "no notes on a drum channel" in w]
    assert "reading channels [1] as drums" in said


def test_the_table_is_general_midis_128_programs() -> None:
    assert len(GM_PROGRAM_NAMES) == 128 == len(set(GM_PROGRAM_NAMES))
    assert (GM_PROGRAM_NAMES[0], GM_PROGRAM_NAMES[40], GM_PROGRAM_NAMES[118], GM_PROGRAM_NAMES[127]) == (
        "Acoustic Grand Piano", "Violin", "Synth Drum", "Gunshot")


def test_a_drum_file_on_channel_1_with_a_daws_default_program_0_is_still_read_with_the_warning() -> None:
    """Many DAWs write program 0 (Acoustic Grand Piano) on every track they export, a drum track on channel 1 too:
    program 0 alone is no choice of a melodic instrument, so the file is read as drums, the warning saying why."""
    score = read_midi(_file([program(0, 0), note(0, 36), note(0, 38), note(0, 42)]))
    assert len(score.events) == 3
    [said] = [w for w in score.warnings if "no notes on a drum channel" in w]
    assert "program 1 (Acoustic Grand Piano) set, a DAW's default, so read as drums" in said
