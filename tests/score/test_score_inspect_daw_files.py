"""A researcher's own DAW files through ``python -m common.score``: a file's length is its bars to the last note's
(a DAW's end of track a little after the last bar made 8 bars "9 bars (32.62 beats)", in render's report.json
too), and an issue repeated on many notes is one line with its count and bars (a 10-minute file printed 37
identical lines)."""

from __future__ import annotations

from pathlib import Path

import mido
import pytest

from common.score.__main__ import bars_words, main
from common.score.summary import score_length
from common.score.text import read_score

TPB = 480


def _daw_file(path: Path, bars: int, tail_ticks: int) -> Path:
    """A type 1 file as a DAW writes one: a tempo track, a drum track on channel 10 of ``bars`` bars of 4/4 (kick,
    snare and eighth hi-hats) and a bass on channel 1, the end of track ``tail_ticks`` after the last bar line."""
    mid = mido.MidiFile(type=1, ticks_per_beat=TPB)
    end = bars * 4 * TPB + tail_ticks
    conductor = mido.MidiTrack([mido.MetaMessage("set_tempo", tempo=500_000),
                                mido.MetaMessage("time_signature", numerator=4, denominator=4),
                                mido.MetaMessage("end_of_track", time=end)])
    notes = [(k * TPB // 2, 42) for k in range(8 * bars)] + [(k * TPB, 36 if k % 2 == 0 else 38)
                                                               for k in range(4 * bars)]
    mid.tracks += [conductor, _track(notes, 9), _track([(k * TPB, 40) for k in range(4 * bars)], 0, program=33)]
    mid.save(str(path))
    return path


def _track(notes: list[tuple[int, int]], channel: int, program: int | None = None) -> mido.MidiTrack:
    events = [(t, 1, mido.Message("note_on", channel=channel, note=p, velocity=100)) for t, p in notes]
    events += [(t + 60, 0, mido.Message("note_off", channel=channel, note=p)) for t, p in notes]
    track = mido.MidiTrack([] if program is None else [mido.Message("program_change", channel=channel,
                                                                     program=program)])
    last = 0
    for tick, _, message in sorted(events, key=lambda e: e[:2]):
        track.append(message.copy(time=tick - last))
        last = tick
    return track


@pytest.mark.parametrize(("tail_ticks", "length"), [
    (TPB * 5 // 8, "32 beats, 8 bars; 16.000 s"),  # the walkthrough's f1: was "32.62 beats, 9 bars; 18.000 s"
    (60, "32 beats, 8 bars; 16.000 s"),  # the last note's note-off, as Reaper writes it
    (0, "32 beats, 8 bars; 16.000 s"),
    (4 * TPB, "36 beats, 9 bars; 18.000 s"),  # a song end set a bar later, on a bar line: its empty bar counts
])
def test_a_daw_files_length_is_its_bars_to_the_last_notes(tail_ticks: int, length: str, tmp_path: Path,
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    path = _daw_file(tmp_path / "f1.mid", 8, tail_ticks)
    assert main([str(path)]) == 0
    first = capsys.readouterr().out.splitlines()[0]
    assert first == f"{path}: 96 events (the last at 15.75 s), {length} to the end of the last bar", first
    # render's report.json (score_beats, score_bars) and its WAV line take the same figures
    beats, bars = length.split(";")[0].replace(" beats", "").split(", ")
    assert score_length(read_score(path)) == (float(beats), int(bars.split()[0]))


def test_an_issue_repeated_on_many_notes_is_one_line_with_its_bars(tmp_path: Path,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    """Three stick notes at once on the last eighth of every other bar: each one's hi-hat goes to the pedal."""
    path = tmp_path / "fills.txt"
    path.write_text("tempo 120\nHH |x.x.x.x.|x.x.x.x.|\nSN |......x.|........|\nT1 |......x.|........|\n"
                    "repeat 5\nSN |x.......|\n")
    assert main([str(path)]) == 0
    issues = [line for line in capsys.readouterr().out.splitlines() if line.startswith("  ") and "->" in line]
    assert issues == ["  6 notes HIHATCLOSED, every 2 bars from bar 1 to bar 11 (the first: note 4 at 1.500 s): "
                      "too_many_hands -> substituted_pedal (3 non-bass events at once: hi-hat pedal instead of a "
                      "stick)"], issues


def test_a_single_issue_keeps_its_note_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "once.txt"
    path.write_text("tempo 120\nHH |x.x.x.x.|x.x.x.x.|\nSN |......x.|........|\nT1 |......x.|........|\n")
    assert main([str(path)]) == 0
    issues = [line for line in capsys.readouterr().out.splitlines() if line.startswith("  ") and "->" in line]
    assert issues == ["  note 4 at 1.500 s HIHATCLOSED: too_many_hands -> substituted_pedal (3 non-bass events at "
                      "once: hi-hat pedal instead of a stick)"], issues


@pytest.mark.parametrize(("bars", "said"), [
    ([8], "bar 8"), ([3, 4, 5, 6], "bars 3 to 6"), ([8, 16, 24, 32], "every 8 bars from bar 8 to bar 32"),
    ([2, 5], "bars 2, 5"), ([2, 5, 11, 5], "bars 2, 5, 11"),
    ([1, 2, 4, 7, 11, 16, 22, 29, 37, 40], "bars 1, 2, 4, 7, 11, 16, 22, ..., 40 (10 bars)"),
])
def test_bars_are_listed_as_a_musician_lists_them(bars: list[int], said: str) -> None:
    assert bars_words(bars) == said
