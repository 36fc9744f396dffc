"""``python -m common.score FILE`` says the score's tempo and time signatures under its first line, as a DAW shows
them (it said neither: a file at 90 bpm in 7/8 read as any other), with their changes and the bar where each
comes; a long list is cut, with its count and range."""

from __future__ import annotations

from pathlib import Path

import mido
import pytest

from common.score.__main__ import main
from common.score.position import counted_bar_beat
from common.score.text import read_score

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


def test_a_tempo_ramp_is_said_as_one_and_a_long_list_cut(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    conductor = [(0, _tempo(100))] + [(k * TPB, _tempo(100 + 2 * k)) for k in range(1, 11)]  # one a beat
    tempo = _header(_midi(tmp_path / "ramp.mid", conductor, 12), capsys)[1]
    # until 8 Dec: "10 (...): 102 bpm at bar 1, beat 2, 104 bpm at bar 1, beat 3, ... (4 more)"
    assert tempo == ("tempo: 100 bpm; tempo changes: 1 (100 to 120 bpm, read beat by beat): accelerando 100 -> 120 bpm "
                     "(10 steps, bar 1, beat 2 to bar 3, beat 3)"), tempo
    # jumps up and down every other beat: no ramp, 8 changes, the first 6 listed
    jumps = [(0, _tempo(100))] + [(2 * k * TPB, _tempo(100 + 20 * (k % 2))) for k in range(1, 9)]
    tempo = _header(_midi(tmp_path / "jumps.mid", jumps, 20), capsys)[1]
    assert tempo == ("tempo: 100 bpm; tempo changes: 8 (100 to 120 bpm, read beat by beat): 120 bpm at bar 1, beat 3, "
                     "100 bpm at bar 2, 120 bpm at bar 2, beat 3, 100 bpm at bar 3, 120 bpm at bar 3, beat 3, 100 bpm "
                     "at bar 4, ... (2 more)"), tempo


def test_an_accelerando_and_the_jumps_after_it_are_all_said(tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    """A researcher's file: 4 bars at 90, an accelerando to 140 over 4 bars (a tempo a beat), 2 bars at 140, a
    sudden 90 for 2 bars, a sudden 140. Until 8 Dec: ``tempo changes: 18 (...): 93.125 bpm at bar 5, 96.2499 bpm at
    bar 5, beat 2, ... (12 more)``: the per-beat steps hid both jumps, and the tempos showed float noise."""
    conductor = [(0, _tempo(90))] + [(16 * TPB + k * TPB, _tempo(90 + 50 * (k + 1) / 16)) for k in range(16)]
    conductor += [(40 * TPB, _tempo(90)), (48 * TPB, _tempo(140))]
    tempo = _header(_midi(tmp_path / "f2.mid", conductor, 56), capsys)[1]
    assert tempo == ("tempo: 90 bpm; tempo changes: 3 (90 to 140 bpm, read beat by beat): accelerando 90 -> 140 bpm "
                     "(16 steps, bar 5 to bar 8, beat 4), 90 bpm at bar 11, 140 bpm at bar 13"), tempo
    # a ritardando straight into a jump the same way: the jump is not the ramp's
    down = [(0, _tempo(120))] + [(k * TPB, _tempo(120 - 2 * k)) for k in range(1, 5)] + [(5 * TPB, _tempo(60))]
    tempo = _header(_midi(tmp_path / "rit.mid", down, 8), capsys)[1]
    assert tempo.endswith("ritardando 120 -> 112 bpm (4 steps, bar 1, beat 2 to bar 2), 60 bpm at bar 2, beat 2"), tempo


@pytest.mark.parametrize(("bpm", "said"), [(96.25, "96.25"), (93.125, "93.13"), (120, "120"), (133.3333, "133.33")])
def test_a_tempo_is_said_to_a_hundredth_of_a_bpm(bpm: float, said: str, tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    """A MIDI tempo is whole microseconds a beat: 96.25 bpm is stored as 96.2499 bpm, said so until 8 Dec."""
    tempo = _header(_midi(tmp_path / "t.mid", [(0, _tempo(bpm))], 4), capsys)[1]
    assert tempo == f"tempo: {said} bpm (no tempo changes)", tempo


def test_a_last_bar_in_a_shorter_meter_is_said_in_it(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Bars of 7/8 then a last one of 6/8: now that a MIDI file ends on the bar line after its last note, that bar
    must not read as one the end cut short (7/8); a text score's last bar of 2/4 after 4/4 read as 4/4 until 8 Dec."""
    conductor = [(0, _meter(7, 8)), (7 * TPB, _meter(6, 8))]
    meter = _header(_midi(tmp_path / "m.mid", conductor, 10), capsys)[2]
    assert meter == "time signature: 7/8; time signature changes: 1: 6/8 at bar 3", meter
    path = tmp_path / "m.txt"
    path.write_text("tempo 120\nmeter 4/4\nSN |xxxx|\nmeter 2/4\nSN |xx|\n")
    assert _header(path, capsys)[2] == "time signature: 4/4; time signature changes: 1: 2/4 at bar 2"
    path.write_text("tempo 120\nmeter 4/4\nSN |xxxx|\nrest 2\n")  # a closing half-bar rest: still 4/4
    assert _header(path, capsys)[2] == "time signature: 4/4"


def test_after_a_pick_up_changes_are_said_at_the_bars_render_bars_counts(tmp_path: Path,
                                                                          capsys: pytest.CaptureFixture[str]) -> None:
    """A beat of pick-up (bar 0), then 4/4 from bar 1, 90 bpm from bar 3 (beat 9), as `batteur render --bars` and the
    issue lines count; until 8 Dec the header said "90 bpm at bar 4" and "4/4 at bar 2"."""
    path = _midi(tmp_path / "pickup.mid", [
        (0, mido.MetaMessage("time_signature", numerator=1, denominator=4)), (0, _tempo(120)),
        (TPB, mido.MetaMessage("time_signature", numerator=4, denominator=4)), (9 * TPB, _tempo(90))], beats=17)
    header = _header(path, capsys)
    assert header[1].endswith(": 90 bpm at bar 3"), header
    assert header[2] == "time signature: 1/4; time signature changes: 1: 4/4 at bar 1", header
    score = read_score(path)
    assert counted_bar_beat(score, score.beats[9])[:2] == (3, 1.0)  # the same bar as the render and issues say
