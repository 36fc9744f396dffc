"""``python -m common.score FILE`` says the score's tempo and time signatures under its first line, as a DAW shows
them (it said neither: a file at 90 bpm in 7/8 read as any other), with their changes and the bar where each
comes; a long list is cut, with its count and range."""

from __future__ import annotations

from pathlib import Path

import mido
import pytest

from common.score.__main__ import main

TPB = 480


def _header(path: Path, capsys: pytest.CaptureFixture[str]) -> list[str]:
    assert main([str(path)]) == 0
    lines = capsys.readouterr().out.splitlines()
    return lines[:next(k for k, line in enumerate(lines) if line.startswith("kit: "))]


def _midi(path: Path, conductor: list[tuple[int, mido.MetaMessage]], beats: int) -> Path:
    """A type 1 file: a conductor track with ``conductor`` (absolute ticks), a snare on every beat on channel 10."""
    mid = mido.MidiFile(type=1, ticks_per_beat=TPB)
    tempo_track, drums = mido.MidiTrack(), mido.MidiTrack()
    tick = 0
    for at, message in conductor:
        tempo_track.append(message.copy(time=at - tick))
        tick = at
    drums.extend(mido.Message("note_on", channel=9, note=38, velocity=100, time=TPB if k else 0)
                 for k in range(beats))
    mid.tracks.extend([tempo_track, drums])
    mid.save(str(path))
    return path


def _tempo(bpm: float) -> mido.MetaMessage:
    return mido.MetaMessage("set_tempo", tempo=mido.bpm2tempo(bpm))


def _meter(numerator: int, denominator: int) -> mido.MetaMessage:
    return mido.MetaMessage("time_signature", numerator=numerator, denominator=denominator)


def test_a_midi_files_tempo_and_meter_changes_are_listed_by_bar(tmp_path: Path,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    # bar 1 of 4/4 at 120, bar 2 of 7/8 (3.5 beats) at 90, bar 3 of 6/8 (3 beats) at 140
    conductor = [(0, _meter(4, 4)), (0, _tempo(120)), (4 * TPB, _meter(7, 8)), (4 * TPB, _tempo(90)),
                 (15 * TPB // 2, _meter(6, 8)), (15 * TPB // 2, _tempo(140))]
    first, tempo, meter = _header(_midi(tmp_path / "a.mid", conductor, 10), capsys)
    # the tempo read beat by beat: the change in the middle of beat 8 is that beat's average
    assert tempo.startswith("tempo: 120 bpm; tempo changes: 3 (90 to 140 bpm, read beat by beat): 90 bpm at bar 2, "
                            ), tempo
    assert tempo.endswith("140 bpm at bar 3, beat 2"), tempo
    assert meter == "time signature: 4/4; time signature changes: 2: 7/8 at bar 2, 6/8 at bar 3", meter
    # to the end of bar 3 (beat 10.5): 4 beats at 120, 3.5 at 90, 3 at 140
    assert first.endswith(f"; {2 + 3.5 * 60 / 90 + 3 * 60 / 140:.3f} s to the end of the last bar"), first


def test_a_steady_score_says_it_has_no_tempo_change(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "score.txt"
    path.write_text("tempo 96\nmeter 3/4\nSN |x.x|x.x|\n")
    assert _header(path, capsys)[1:] == ["tempo: 96 bpm (no tempo changes)", "time signature: 3/4"]


def test_a_text_scores_changes_come_at_their_bars(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "score.txt"
    path.write_text("tempo 100\nmeter 4/4\nSN |x.x.|\ntempo 150\nmeter 6/8\nSN |x..x..|\n")
    assert _header(path, capsys)[1:] == ["tempo: 100 bpm; tempo changes: 1 (100 to 150 bpm, read beat by beat): "
                                         "150 bpm at bar 2",
                                         "time signature: 4/4; time signature changes: 1: 6/8 at bar 2"]


def test_a_tempo_ramp_is_counted_and_its_list_cut(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    conductor = [(0, _tempo(100))] + [(k * TPB, _tempo(100 + 2 * k)) for k in range(1, 11)]  # one a beat
    tempo = _header(_midi(tmp_path / "ramp.mid", conductor, 12), capsys)[1]
    assert tempo.startswith("tempo: 100 bpm; tempo changes: 10 (100 to 120 bpm, read beat by beat): 102 bpm at "
                            "bar 1, beat 2, "), tempo
    assert tempo.endswith("112 bpm at bar 2, beat 3, ... (4 more)"), tempo
