"""Which MIDI channels are read as drums: notes left out are said (channels, notes, programs, tracks, and the
option that reads them); without a note on channel 10 a bass or a piano beside the drums is skipped, said why;
``--drum-channels 1,10`` chooses (those channels only) on every command that reads a score; several tracks
playing one pitch at the same time (one drum per track, all on the DAW's note 60) are named."""

from __future__ import annotations

import argparse
import io
from pathlib import Path

import mido
import pytest

from common.kit import EventType as E
from common.score.__main__ import main as inspect_main
from common.score.midi import read_midi
from common.score.midi_options import add_midi_arguments, drum_channels, midi_read_kwargs

GROOVE = [(0, 36), (0, 42), (240, 42), (480, 38), (480, 42), (720, 42)]
"""A beat of drums: (tick, pitch) at 480 ticks a beat."""


def smf(tracks: list[tuple[str, int, list[tuple[int, int]], int | None]]) -> bytes:
    """A type 1 file at 120 bpm: each track (name, channel index, (tick, pitch) notes, GM program or None)."""
    mid = mido.MidiFile(type=1, ticks_per_beat=480)
    for title, channel, notes, program in tracks:
        track = mido.MidiTrack()
        track.append(mido.MetaMessage("track_name", name=title))
        if program is not None:
            track.append(mido.Message("program_change", channel=channel, program=program))
        events = [(tick, 1, mido.Message("note_on", channel=channel, note=pitch, velocity=100))
                  for tick, pitch in notes]
        events += [(tick + 10, 0, mido.Message("note_off", channel=channel, note=pitch)) for tick, pitch in notes]
        last = 0
        for tick, _, msg in sorted(events, key=lambda e: e[:2]):
            track.append(msg.copy(time=tick - last))
            last = tick
        mid.tracks.append(track)
    buf = io.BytesIO()
    mid.save(file=buf)
    return buf.getvalue()


DRUM_RACK_AND_TAMBOURINE = smf([("Drums", 0, GROOVE, None), ("Tambourine", 9, [(0, 54), (480, 54)], None)])
"""Ableton's Drum Rack on channel 1, a tambourine on channel 10."""


def test_notes_left_out_beside_channel_10_are_said_with_the_option_that_reads_them() -> None:
    score = read_midi(DRUM_RACK_AND_TAMBOURINE)
    assert [e.event for e in score.events] == [E.HIHATOPEN, E.HIHATOPEN]  # channel 10 alone, as before
    [said] = [w for w in score.warnings if "skipped" in w]
    assert "skipped channel 1 (6 notes, track Drums)" in said
    assert "--drum-channels 1,10" in said


def test_a_melodic_channel_beside_channel_10_is_said_to_be_one() -> None:
    song = smf([("Drums", 9, GROOVE, None), ("Bass", 0, [(0, 40), (480, 47)], 33)])
    score = read_midi(song)
    assert len(score.events) == 6
    [said] = score.warnings
    assert "skipped channel 1 (2 notes, Electric Bass (finger), track Bass): a melodic program; to read it too: " \
           "--drum-channels 1,10" in said


def test_drum_channels_reads_those_channels_only() -> None:
    only_rack = read_midi(DRUM_RACK_AND_TAMBOURINE, drum_channels=[1])  # until 7 Dec: channel 10 as well
    assert sorted(e.event.value for e in only_rack.events) == ["BASS", "HIHATCLOSED", "HIHATCLOSED",
                                                               "HIHATCLOSED", "HIHATCLOSED", "SNARE"]
    assert not only_rack.warnings
    both = read_midi(DRUM_RACK_AND_TAMBOURINE, drum_channels=[1, 10])
    assert len(both.events) == 8 and not any("skipped" in w for w in both.warnings)
    nothing = read_midi(DRUM_RACK_AND_TAMBOURINE, drum_channels=[2])
    assert not nothing.events
    assert any("no notes on channel 2 (--drum-channels); notes are on channel 1 (6 notes, track Drums); "
               "channel 10 (2 notes, track Tambourine)" in w for w in nothing.warnings)


def test_without_channel_10_a_melodic_channel_beside_the_drums_is_skipped_and_said() -> None:
    bass = smf([("Drums", 0, GROOVE, None), ("Bass", 1, [(0, 40), (480, 47)], 33)])
    score = read_midi(bass)
    assert len(score.events) == 6 and {e.pitch for e in score.events} == {36, 38, 42}  # no bass note as a tom
    [said] = [w for w in score.warnings if "no notes on a drum channel" in w]
    assert "reading channels [1] as drums" in said
    assert "skipped channel 2 (2 notes, Electric Bass (finger), track Bass): a melodic program" in said
    assert "--drum-channels" in said


def test_a_file_of_melodic_channels_only_is_refused_never_emptied_in_silence_nor_played_as_drums(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A bass line alone (channel 1, a bass program) was read as drums with only a warning, exit 0: the render
    played it on the snare. A drum file on channel 1 without a program change is still read (the test above)."""
    bass = tmp_path / "bass.mid"
    bass.write_bytes(smf([("Bass", 0, [(0, 40), (480, 42), (960, 44)], 33)]))
    assert inspect_main([str(bass)]) == 1
    err = capsys.readouterr().err
    assert err == (f"python -m common.score: error: {bass}: no drums: no notes on a drum channel (10, or one set to a "
                   "drum bank), and the notes are on channel 1 (3 notes, Electric Bass (finger), track Bass), set to a "
                   "melodic program; to read it as drums anyway: --drum-channels 1\n")
    assert inspect_main([str(bass), "--drum-channels", "1"]) == 0  # the way the error names
    assert "  SNARE        1" in capsys.readouterr().out


@pytest.mark.parametrize("title", ["Click", "Metronome", "Count-in", "Guide", "click track 2", "ClickTrack",
                                   "Klick", "Custom Click", "Click (Override)", "Bottom guide"])
def test_a_click_track_beside_the_drums_is_left_out_and_said(title: str) -> None:
    # until 7 Dec read as drums (wood blocks played as cowbells) when nothing was on channel 10; "Custom Click",
    # "Click (Override)" and "Bottom guide" until the day after: "tom" and "ride" inside a word said drums
    take = smf([("Drums", 0, GROOVE, None), (title, 15, [(0, 76), (480, 77), (960, 76)], None)])
    score = read_midi(take)
    assert sorted(e.pitch for e in score.events) == [36, 38, 42, 42, 42, 42]
    [said] = [w for w in score.warnings if "no notes on a drum channel" in w]
    assert "reading channels [1] as drums" in said
    assert f"skipped channel 16 (3 notes, track {title}): a click (so named, on 2 pitches); to read it too: " \
           "--drum-channels 1,16" in said
    assert len(read_midi(take, drum_channels=[1, 16]).events) == 9  # the option reads it


@pytest.mark.parametrize(("tracks", "why"), [
    ([("Drums", 0, GROOVE, None), ("Click", 15, [(0, 75), (240, 76), (480, 77)], None)], "three pitches: a part"),
    ([("Drums", 0, GROOVE, None), ("Guide Drums", 15, [(240, 36), (720, 38)], None)], "drums in its name"),
    ([("Drums", 0, GROOVE, None), ("Perc", 15, [(0, 76), (480, 77)], None)], "not named a click"),
    ([("Click", 15, [(0, 76), (480, 77)], None)], "nothing else to read: read as before"),
    ([("Hats", 0, [(0, 42), (240, 42), (480, 42)], None), ("Click", 1, [(0, 36), (480, 38)], None)],
     "a kick and a snare: a part"),
    ([("Drums", 0, GROOVE, None), ("Guide", 15, [(240, 35), (720, 35)], None)], "a kick alone: a part"),
    ([("Drums", 0, GROOVE, None), ("Hi-Hat Guide", 15, [(120, 42), (360, 46)], None)], "a drum in its name"),
    ([("Drums", 0, GROOVE, None), ("KickDrum click", 15, [(0, 76), (480, 77)], None)], "drums, in camel case"),
])
def test_a_channel_is_left_out_as_a_click_only_when_it_is_one(
        tracks: list[tuple[str, int, list[tuple[int, int]], int | None]], why: str) -> None:
    score = read_midi(smf(tracks))
    assert len(score.events) == sum(len(notes) for _, _, notes, _ in tracks), why
    assert not any("a click" in w for w in score.warnings), why


def test_a_click_and_a_bass_are_both_said_when_left_out() -> None:
    song = smf([("Drums", 0, GROOVE, None), ("Bass", 1, [(0, 40), (480, 47)], 33),
                ("Metronome", 15, [(0, 76)], None)])
    score = read_midi(song)
    assert len(score.events) == 6
    [said] = [w for w in score.warnings if "no notes on a drum channel" in w]
    assert "skipped channel 16 (1 note, track Metronome): a click (so named, on 1 pitch); to read it too: " \
           "--drum-channels 1,16" in said
    assert "skipped channel 2 (2 notes, Electric Bass (finger), track Bass): a melodic program" in said


def smf0(title: str, notes: list[tuple[int, int, int]]) -> bytes:
    """A type 0 file at 120 bpm: its one track named ``title``, holding (tick, channel index, pitch) notes."""
    mid = mido.MidiFile(type=0, ticks_per_beat=480)
    track = mido.MidiTrack([mido.MetaMessage("track_name", name=title)])
    last = 0
    for tick, channel, pitch in sorted(notes):
        track.append(mido.Message("note_on", channel=channel, note=pitch, velocity=100, time=tick - last))
        track.append(mido.Message("note_off", channel=channel, note=pitch, time=0))
        last = tick
    mid.tracks.append(track)
    buf = io.BytesIO()
    mid.save(file=buf)
    return buf.getvalue()


@pytest.mark.parametrize("first", [(42, 46), (36, 38)])
def test_a_track_on_several_channels_is_no_click_whatever_its_name(first: tuple[int, int]) -> None:
    # a type 0 file's one track, named Guide: channel 1 (hi-hats, or a kick and a snare: two pitches) was dropped
    # as a click until 7 Dec, and only channel 2's hi-hats and crash played
    notes = [(k * 480 + 120, 0, first[k % 2]) for k in range(8)]
    notes += [(k * 240, 1, 42) for k in range(16)] + [(0, 1, 49), (3600, 1, 51)]
    score = read_midi(smf0("Guide", notes))
    assert len(score.events) == len(notes)
    assert not any("a click" in w or "clicks" in w for w in score.warnings)
    assert any("reading channels [1, 2] as drums" in w for w in score.warnings)


def test_clicks_on_several_channels_say_each_one_s_pitches() -> None:
    # until 7 Dec counted together: "a click (so named, on 3 pitches)", "on 4 pitches"
    mixed = smf([("Drums", 0, GROOVE, None), ("Click", 14, [(0, 76), (480, 77)], None),
                 ("Count-in", 15, [(0, 33), (480, 33)], None)])
    [said] = [w for w in read_midi(mixed).warnings if "skipped" in w]
    assert "track Count-in): clicks (so named; channel 15 on 2 pitches, channel 16 on 1 pitch); to read them " \
           "too: --drum-channels 1,15,16" in said
    alike = smf([("Drums", 0, GROOVE, None), ("Click", 14, [(0, 76), (480, 77)], None),
                 ("Count-in", 15, [(0, 33), (480, 34)], None)])
    [said] = [w for w in read_midi(alike).warnings if "skipped" in w]
    assert "clicks (so named, on 2 pitches each)" in said


def test_a_guide_s_kick_and_snare_are_judged_as_the_drum_map_maps_them() -> None:
    # the file's own layout (kick 24, snare 26) through --drum-map: a kick and a snare, a part; without the map,
    # two pitches of no drum on a Guide track: a click, as before
    take = smf([("Hats", 0, [(0, 42), (240, 42), (480, 42)], None), ("Guide", 1, [(0, 24), (480, 26)], None)])
    assert any("a click (so named, on 2 pitches)" in w for w in read_midi(take).warnings)
    mapped = read_midi(take, note_map={24: 36, 26: 38})
    assert sorted(e.pitch for e in mapped.events) == [36, 38, 42, 42, 42]
    assert not any("a click" in w for w in mapped.warnings)


def test_tracks_playing_one_pitch_at_the_same_time_are_named() -> None:
    split = smf([("Kick", 0, [(0, 60), (960, 60)], None), ("Snare", 1, [(480, 60), (1440, 60)], None),
                 ("Hats", 2, [(t, 60) for t in range(0, 1920, 240)], None)])
    [said] = [w for w in read_midi(split).warnings if "played by" in w]
    assert "pitch 60 is played by 3 tracks, Kick (channel 1), Snare (channel 2), Hats (channel 3), 4 times at " \
           "the same tick" in said
    assert "own pitch" in said


def test_tracks_playing_one_pitch_a_note_map_moves_are_named_by_the_files_pitch() -> None:
    # until 7 Dec the pitches were compared after the map: a map moving 60 hid the warning, and a map swapping
    # two pitches named the wrong drum. Two pitches the map plays on one drum (a tom's head and rim on tracks of
    # their own, 58 -> 43) are two pitches, not one shared: only 60 is named (the rim case alone passed before)
    split = smf([("Kick", 0, [(0, 60), (960, 60)], None), ("Snare", 1, [(0, 60), (960, 60)], None),
                 ("Tom", 2, [(0, 43), (480, 43)], None), ("Tom rim", 3, [(0, 58), (480, 58)], None)])
    [said] = [w for w in read_midi(split, note_map={60: 38, 58: 43}).warnings if "played by" in w]
    assert "pitch 60 is played by 2 tracks, Kick (channel 1), Snare (channel 2), 2 times at the same tick" in said
    assert "one drum here (SNARE)" in said
    swapped = smf([("Kick", 0, [(0, 36), (960, 36)], None), ("Kick 2", 1, [(0, 36), (960, 36)], None),
                   ("Snare", 2, [(480, 38)], None), ("Snare 2", 3, [(480, 38)], None)])
    said_swapped = [w for w in read_midi(swapped, note_map={36: 38, 38: 36}).warnings if "played by" in w]
    assert len(said_swapped) == 2
    assert "pitch 36 is played by 2 tracks, Kick (channel 1), Kick 2 (channel 2), 2 times" in said_swapped[0]
    assert "one drum here (SNARE)" in said_swapped[0]  # the drum the map plays it on
    assert "pitch 38 is played by 2 tracks, Snare (channel 3), Snare 2 (channel 4), 1 time " in said_swapped[1]
    assert "one drum here (BASS)" in said_swapped[1]


def test_tracks_on_their_own_pitches_or_at_other_times_are_not_named() -> None:
    split = smf([("Kick", 9, [(0, 36), (960, 36)], None), ("Hats", 9, [(0, 42), (480, 42), (960, 42)], None),
                 ("Kick 2", 9, [(480, 36)], None)])
    assert not any("played by" in w for w in read_midi(split).warnings)


@pytest.mark.parametrize(("given", "channels"), [("1,10", (1, 10)), ("10", (10,)), (" 16 , 1,1", (16, 1))])
def test_drum_channels_are_read_as_a_daw_shows_them(given: str, channels: tuple[int, ...]) -> None:
    assert drum_channels(given) == channels


@pytest.mark.parametrize(("given", "says"), [
    ("0", "channel 0 is not a MIDI channel, 1 to 16 (channels count from 1"),
    ("17", "channel 17 is not a MIDI channel, 1 to 16"),
    ("1,x", "'x' is not a channel number"),
    ("", "expected MIDI channels 1 to 16 separated by commas"),
])
def test_a_channel_out_of_range_is_a_clear_error(given: str, says: str) -> None:
    with pytest.raises(argparse.ArgumentTypeError, match=says.replace("(", r"\(")):
        drum_channels(given)


def test_the_options_become_read_midi_arguments() -> None:
    parser = argparse.ArgumentParser()
    add_midi_arguments(parser)
    assert midi_read_kwargs(parser.parse_args([])) == {}  # the reader's own choice
    assert midi_read_kwargs(parser.parse_args(["--drum-channels", "1,10"]))["drum_channels"] == (1, 10)


def test_python_m_common_score_takes_drum_channels(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "rack.mid"
    path.write_bytes(DRUM_RACK_AND_TAMBOURINE)
    assert inspect_main([str(path), "--drum-channels", "1"]) == 0
    out = capsys.readouterr().out
    assert "6 events" in out and "HIHATOPEN" not in out
    with pytest.raises(SystemExit) as refused:
        inspect_main([str(path), "--drum-channels", "17"])
    assert refused.value.code == 2
    assert "--drum-channels: '17': channel 17 is not a MIDI channel, 1 to 16" in capsys.readouterr().err
