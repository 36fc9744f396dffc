"""``python -m common.score FILE`` says how long a score is as a musician counts it: a one-note bar of ``meter 1/4``
was "2 beats", a bar of four quarter notes in 4/4 "5 beats": it counted :attr:`Score.beats`, which holds the beat
at the end as well (the head nod's last). Now the beats (quarter notes) and bars up to the score's end
(:attr:`Score.end_beat`), and the seconds to the end of the last bar (the last note's time is said as such: "over
1.50 s" read as the score's length, a bar short of it)."""

from __future__ import annotations

from pathlib import Path

import mido
import pytest

from common.score.__main__ import main
from common.score.events import MAX_SCORE_BARS
from common.score.text import read_score


def _first_line(path: Path, capsys: pytest.CaptureFixture[str]) -> str:
    assert main([str(path)]) == 0
    return capsys.readouterr().out.splitlines()[0]


@pytest.mark.parametrize(("text", "length"), [
    ("meter 1/4\nSN |x|\n", "1 event (the last at 0.00 s), 1 beat, 1 bar; 0.500 s"),  # was "2 beats"
    ("meter 4/4\nSN |xxxx|\n", "4 events (the last at 1.50 s), 4 beats, 1 bar; 2.000 s"),  # was "5 beats"
    ("meter 3/4\nSN |xxx|xxx|\n", "6 events (the last at 2.50 s), 6 beats, 2 bars; 3.000 s"),
    # six eighths: three quarter notes
    ("meter 6/8\nSN |xxxxxx|\n", "6 events (the last at 1.25 s), 3 beats, 1 bar; 1.500 s"),
    ("meter 7/8\nSN |xxxxxxx|\n", "7 events (the last at 1.50 s), 3.5 beats, 1 bar; 1.750 s"),
    ("meter 1/8\nSN |x|\n", "1 event (the last at 0.00 s), 0.5 beats, 1 bar; 0.250 s"),
    # a closing half-bar rest: the score ends inside bar 3, which ends 2 beats later
    ("SN |xxxx|\nrepeat 1\nrest 2\n", "8 events (the last at 3.50 s), 10 beats, 3 bars; 6.000 s"),
    ("at 0 SN\n", "1 event (the last at 0.00 s), 4 beats, 1 bar; 2.000 s"),  # `at` lines only: the note's bar
    # was "10001.2 beats": six significant digits
    ("meter 7/16\nSN |x.x.x.x|\nrepeat 5714\n",
     "22860 events (the last at 5000.50 s), 10001.25 beats, 5715 bars; 5000.625 s"),
])
def test_a_text_score_reports_its_beats_and_bars(text: str, length: str, tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "score.txt"
    path.write_text("tempo 120\n" + text)
    assert _first_line(path, capsys) == f"{path}: {length} to the end of the last bar"


@pytest.mark.parametrize(("end_beats", "length"), [(4.0, "4 beats, 1 bar; 2.000 s"),
                                                   (3.5, "4 beats, 1 bar; 2.000 s"),  # bar 1 ends at beat 4
                                                   # an end of track on a bar line: its empty bar counts
                                                   (8.0, "8 beats, 2 bars; 4.000 s"),
                                                   # a DAW's end of track a little after the last bar: not a bar
                                                   # more (was "4.62 beats, 2 bars"), nor inside a later one
                                                   (4.625, "4 beats, 1 bar; 2.000 s"),
                                                   (9.5, "4 beats, 1 bar; 2.000 s")])
def test_a_midi_file_reports_its_beats_and_bars_to_its_end(end_beats: float, length: str, tmp_path: Path,
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    mid = mido.MidiFile(type=0, ticks_per_beat=480)
    track = mido.MidiTrack()
    mid.tracks.append(track)
    for i in range(4):  # four quarter-note snares in 4/4, 120 bpm (a MIDI file's defaults)
        track.append(mido.Message("note_on", channel=9, note=38, velocity=100, time=480 if i else 0))
    track.append(mido.MetaMessage("end_of_track", time=round((end_beats - 3) * 480)))
    path = tmp_path / "score.mid"
    mid.save(str(path))
    # was one beat more when whole; "over 1.50 s", the last note's time
    assert _first_line(path, capsys) == f"{path}: 4 events (the last at 1.50 s), {length} to the end of the last bar"


def test_a_midi_file_longer_than_the_bars_counted_says_at_least(tmp_path: Path,
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    # a note, then 2**28 ticks of silence at 96 per beat: the reader stops counting bars at MAX_SCORE_BARS
    mid = mido.MidiFile(type=0, ticks_per_beat=96)
    track = mido.MidiTrack()
    mid.tracks.append(track)
    track.append(mido.Message("note_on", channel=9, note=38, velocity=100, time=0))
    track.append(mido.MetaMessage("end_of_track", time=2**28 - 2**28 % (4 * 96)))  # on a bar line: the end
    path = tmp_path / "score.mid"
    mid.save(str(path))
    line = _first_line(path, capsys)
    assert f"2796200 beats, at least {MAX_SCORE_BARS} bars; " in line, line  # was "2.7962e+06 beats"


def test_the_beats_still_hold_the_one_at_the_end(tmp_path: Path) -> None:
    # the head nod's and the position's beats are not what changed: a bar of 4/4 has its 5 beat times, 0 to 4
    path = tmp_path / "score.txt"
    path.write_text("tempo 120\nmeter 4/4\nSN |xxxx|\n")
    score = read_score(path)
    assert list(score.beats) == [0.0, 0.5, 1.0, 1.5, 2.0] and score.end_beat == 4.0
