"""A MIDI file whose tempo no music is played at is read as it is, with a warning saying how long it then lasts: a
set_tempo of 1 microsecond a beat (60,000,000 bpm) rendered as "29 double notes merged" with no word of the tempo."""

from __future__ import annotations

import io
import json
from pathlib import Path

import mido
import pytest

from common.score.midi import read_midi
from common.score.text import read_score

TPB = 480


def _snares(tempos: list[tuple[int, int]], notes: int = 30, end_tick: int | None = None) -> bytes:
    """A type 0 file: ``tempos`` (tick, microseconds a beat) and ``notes`` snare notes a beat apart from tick 0,
    each 10 ticks long; its end at ``end_tick`` when given (past the last note off)."""
    timed = [(t, mido.MetaMessage("set_tempo", tempo=us)) for t, us in tempos]
    for k in range(notes):
        timed += [(k * TPB, mido.Message("note_on", channel=9, note=38, velocity=100)),
                  (k * TPB + 10, mido.Message("note_off", channel=9, note=38, velocity=0))]
    if end_tick is not None:
        timed.append((end_tick, mido.MetaMessage("marker", text="end")))
    track, now = mido.MidiTrack(), 0
    for tick, msg in sorted(timed, key=lambda tm: tm[0]):  # stable: tempos first at a tick
        track.append(msg.copy(time=tick - now))
        now = tick
    mid = mido.MidiFile(type=0, ticks_per_beat=TPB)
    mid.tracks.append(track)
    buf = io.BytesIO()
    mid.save(file=buf)
    return buf.getvalue()


def test_a_tempo_of_one_microsecond_a_beat_is_warned_with_the_files_length(tmp_path: Path) -> None:
    path = tmp_path / "fast.mid"
    path.write_bytes(_snares([(0, 1)]))
    score = read_score(path)  # what render reads: its warnings printed and kept in report.json
    # a beat is 1 us: the 30th note at 29 us, the file's end (its note off) at 29 + 10/480 us
    assert score.warnings[0] == (f"{path}: tempo 60,000,000 bpm at tick 0 (a set_tempo of 1 microsecond a beat), "
                                 "outside the 20 to 400 bpm music is played at: read as it is, the whole file lasts "
                                 "0.029 ms, its 30 notes between 0 s and 0.029 ms (a corrupt tempo? set the tempo "
                                 "in the DAW and export again)"), score.warnings
    assert len(score.events) >= 1  # read, not refused


def test_a_very_slow_tempo_is_warned_too() -> None:
    score = read_midi(_snares([(0, 6_000_000)], notes=4))  # 10 bpm: a beat 6 s
    assert score.warnings == ["<bytes>: tempo 10 bpm at tick 0 (a set_tempo of 6,000,000 microseconds a beat), "
                              "outside the 20 to 400 bpm music is played at: read as it is, the whole file lasts "
                              "18.1 s, its 4 notes between 0 s and 18 s (a corrupt tempo? set the tempo in the DAW "
                              "and export again)"]
    assert [e.time for e in score.events] == [0.0, 6.0, 12.0, 18.0]


def test_several_odd_tempos_are_one_warning() -> None:
    # 120 bpm, then 600 bpm from beat 1, 3.75 bpm from beat 2, 120 from beat 3
    score = read_midi(_snares([(0, 500_000), (TPB, 100_000), (2 * TPB, 16_000_000), (3 * TPB, 500_000)], notes=4))
    assert score.warnings == ["<bytes>: 2 tempos outside the 20 to 400 bpm music is played at, from 3.75 to 600 bpm, "
                              "the first tempo 600 bpm at tick 480 (a set_tempo of 100,000 microseconds a beat): read "
                              "as they are, the whole file lasts 16.6 s, its 4 notes between 0 s and 16.6 s (a "
                              "corrupt tempo? set the tempo in the DAW and export again)"]


def test_tempos_that_hold_nothing_or_are_played_are_not_warned() -> None:
    assert read_midi(_snares([(0, 3_000_000)], notes=4)).warnings == []  # 20 bpm
    assert read_midi(_snares([(0, 150_000)], notes=4)).warnings == []  # 400 bpm
    # replaced at its own tick, or set at the file's very end: no note nor beat is read at it
    assert read_midi(_snares([(0, 1), (0, 500_000)], notes=4)).warnings == []
    assert read_midi(_snares([(0, 500_000), (4 * TPB, 1)], notes=4, end_tick=4 * TPB)).warnings == []
    # but one that holds the silence after the notes makes the file last that long: said
    said = read_midi(_snares([(0, 500_000), (4 * TPB, 1)], notes=4, end_tick=8 * TPB)).warnings
    assert len(said) == 1 and "tempo 60,000,000 bpm at tick 1920" in said[0], said


def test_render_prints_the_tempo_warning_and_keeps_it_in_the_report(tmp_path: Path,
                                                                     capsys: pytest.CaptureFixture[str]) -> None:
    from batteur import render

    path = tmp_path / "fast.mid"
    path.write_bytes(_snares([(0, 1)], notes=3))
    out = tmp_path / "out"
    assert render.main([str(path), "-o", str(out), "--quiet"]) == 0
    said = f"{path}: tempo 60,000,000 bpm at tick 0"
    assert f"batteur render: warning: {said}" in capsys.readouterr().err
    assert any(w.startswith(said) for w in json.loads((out / "report.json").read_text())["warnings"])
