"""Score readers against what users feed them: broken and extreme MIDI files, hand-written text with typos."""

from __future__ import annotations

import io
import struct
from pathlib import Path

import mido
import numpy as np
import pytest

from common.kit import EventType as E
from common.kit import load_kit
from common.score import limbs
from common.score.events import MAX_SCORE_BYTES, MAX_SCORE_NOTES, DrumEvent, Score, ScoreError
from common.score.midi import MAX_BEATS, read_midi
from common.score.text import parse_text, read_score


def _smf(track: bytes, division: int = 96) -> bytes:
    return b"MThd" + struct.pack(">IHHH", 6, 0, 1, division) + b"MTrk" + struct.pack(">I", len(track)) + track


def _delta(ticks: int) -> bytes:
    """A MIDI variable-length quantity (a delta time)."""
    out = [ticks & 0x7F]
    while ticks > 0x7F:
        ticks >>= 7
        out.insert(0, (ticks & 0x7F) | 0x80)
    return bytes(out)


def _snares(n: int, tempo: int = 500000, tpb: int = 96, step: int = 48) -> bytes:
    """A type 0 file of a tempo then ``n`` snare notes (channel 10) ``step`` ticks apart: the bytes mido saves
    (running status), put together directly: mido's 500,001 Message objects took 3.3 s of CPU."""
    notes = b"\x00\x99\x26\x64" + (_delta(step) + b"\x26\x64") * (n - 1) if n else b""
    return _smf(b"\x00\xff\x51\x03" + tempo.to_bytes(3, "big") + notes + b"\x00\xff\x2f\x00", division=tpb)


# --- MIDI ------------------------------------------------------------------------------------------------------

def test_a_corrupt_delta_time_is_an_error_naming_the_tick_not_a_hang() -> None:
    # a delta of 2^28 - 1 ticks puts the second note 388 h in: planning hung and a terabyte array was asked for
    data = _smf(b"\x00\x99\x26\x64" + b"\xff\xff\xff\x7f\x99\x26\x64" + b"\x00\xff\x2f\x00")
    with pytest.raises(ScoreError, match=r"<bytes>: a note at tick 268435455 sounds 388.4 h in"):
        read_midi(data)


def test_a_long_silence_after_the_notes_keeps_the_notes_and_bounded_beats() -> None:
    # the file ends 2^28 ticks after its only note (at one tick a beat): the beats were a 4 TB array
    data = _smf(b"\x00\x99\x26\x64" + b"\xff\xff\xff\x7f\xff\x2f\x00", division=1)
    score = read_midi(data)
    assert [e.event for e in score.events] == [E.SNARE]
    assert len(score.beats) == MAX_BEATS


def test_tempo_zero_is_an_error() -> None:
    # every note after it sounded at once, and all but one were reported as doubles of the first
    with pytest.raises(ScoreError, match="tempo 0 at tick 0"):
        read_midi(_snares(8, tempo=0))


def test_a_bad_key_signature_is_ignored_with_a_warning() -> None:
    # mido's KeySignatureError is no ValueError: a traceback from `batteur render`, then the whole file refused
    data = _smf(b"\x00\xff\x59\x02\x00\x2f" + b"\x00\x99\x26\x64\x00\xff\x2f\x00")
    score = read_midi(data)
    assert [e.event for e in score.events] == [E.SNARE]
    assert score.warnings == ["<bytes>: a key signature that cannot be read ignored (a drum score needs no key; "
                              "Could not decode key with 0 flats and mode 47)"]


def test_too_many_notes_and_too_large_files_are_refused(tmp_path: Path) -> None:
    with pytest.raises(ScoreError, match=f"more than the {MAX_SCORE_NOTES}"):
        read_midi(_snares(MAX_SCORE_NOTES + 1, step=1))
    big = tmp_path / "big.mid"
    big.write_bytes(_snares(4) + bytes(MAX_SCORE_BYTES))
    with pytest.raises(ScoreError, match="big.mid: .* too large"):
        read_midi(big)


def test_type_1_merge_is_mido_order() -> None:
    # the merge without mido's copies keeps merge_tracks' order (ties in track order) and the file's end
    rng = np.random.default_rng(3)
    mid = mido.MidiFile(type=1, ticks_per_beat=120)
    for k in range(4):
        track = mido.MidiTrack()
        for _ in range(60):
            kind = rng.integers(3)
            t = int(rng.integers(0, 40))
            if kind == 0:
                track.append(mido.MetaMessage("set_tempo", tempo=int(rng.integers(200000, 900000)), time=t))
            else:
                track.append(mido.Message("note_on", note=int(rng.choice([36, 38, 42, 46])),
                                          velocity=int(rng.integers(1, 128)), channel=9, time=t))
        track.append(mido.MetaMessage("end_of_track", time=int(rng.integers(0, 500)) * k))
        mid.tracks.append(track)
    buf = io.BytesIO()
    mid.save(file=buf)
    score = read_midi(buf.getvalue())
    ticks, seconds, tempo = 0, 0.0, 500000
    expected = []
    for msg in mido.merge_tracks(mid.tracks):
        ticks += msg.time
        seconds += msg.time * tempo / 1e6 / 120
        if msg.type == "set_tempo":
            tempo = msg.tempo
        elif msg.type == "note_on":
            expected.append(seconds)
    assert len(score.events) + len(score.duplicates) == len(expected)
    assert sorted(e.time for e in score.events + score.duplicates) == pytest.approx(sorted(expected))
    assert len(score.beats) == ticks // 120 + 1


# --- text ------------------------------------------------------------------------------------------------------

@pytest.mark.parametrize(
    "text, message",
    [
        ("at nan SN", "line 1: the beat must be a finite number"),
        ("at inf SN", "finite"),
        ("at 1e20 SN", "line 1: the score would last"),
        ("rest nan\nSN |x...|", "line 1: a rest must be a finite number"),
        ("rest -8\nSN |x...|", "line 1: a rest cannot be negative"),
        ("rest 200000\nSN |x...|", "line 1: the score would last 27.78 h"),
        ("at -5 SN", "line 1: beat -5 is before the start"),
        ("meter nan/4\nSN |x...|", "line 1: cannot read 'meter nan/4'"),
        ("meter 1e300/4\nSN |x...|\nSN |x...|", "line 2: the score would last"),
        ("SN |x...|\nrepeat 600000", "line 2: the score would hold 600001 notes"),
        ("SN |x²..|", "line 1: cell 2: unknown character '²'"),
        ("at 1 SN 0.5 Q", "line 1: the hand must be L or R"),
        ("SN |x...|\nST |r...|", "line 2: ST cell 1: unknown character 'r'"),
        ("SN |x...|\nNU |A...|", "line 2: NU cell 1"),
        ("SN |x...|\nST |R...|\nST |L...|", "line 3: a second ST row"),
    ],
)
def test_text_typos_and_extremes_are_line_errors(text: str, message: str) -> None:
    # before: planner tracebacks (NaN, inf, 1e20), numpy's 'arange: cannot compute length' or 'Maximum allowed
    # size exceeded' without file or line, hangs (rest 1e9, repeat 1e8), or the typo silently ignored
    with pytest.raises(ScoreError, match=message):
        parse_text(text)


def test_text_errors_name_the_file(tmp_path: Path) -> None:
    p = tmp_path / "beat.txt"
    p.write_text("at nan SN\n", encoding="utf-8")
    with pytest.raises(ScoreError, match=r"beat.txt: line 1: the beat must be a finite number"):
        read_score(p)


def test_byte_order_mark_and_tabs_are_read(tmp_path: Path) -> None:
    # Notepad's UTF-8 BOM made the first row an "unknown instrument '\ufeffSN'"; a tab after a name an
    # "unknown directive"
    p = tmp_path / "win.txt"
    p.write_bytes("\ufeffSN\t|x...|\ntempo\t60\nBD\t|x...|\n".encode())
    score = read_score(p)
    assert [(e.time, e.event) for e in score.events] == [(0.0, E.SNARE), (2.0, E.BASS)]


def test_a_row_named_twice_plays_both_rows() -> None:
    # the second SN row replaced the first: its notes were lost without a word
    score = parse_text("SN |x...|\nSN |..x.|\n")
    assert [e.time for e in score.events] == [0.0, 1.0]


def test_many_tempo_lines_read_in_linear_work(monkeypatch: pytest.MonkeyPatch) -> None:
    # a tempo line per bar: every beat's time scanned every tempo change (7 h of bars took 50 s)
    import common.score.text as text_module

    calls = {"n": 0}
    real = text_module.bisect.bisect_right

    def counting(a: list[float], x: float) -> int:
        calls["n"] += 1
        return real(a, x)

    monkeypatch.setattr(text_module.bisect, "bisect_right", counting)
    bars = 300
    score = parse_text("".join(f"tempo {100 + i % 50}\nHH |x.x.|\n" for i in range(bars)))
    assert len(score.events) == 2 * bars
    assert len(score.beats) == 4 * bars + 1
    assert calls["n"] <= 2 * (len(score.events) + len(score.beats))  # a lookup or two per note, block and beat


def test_the_tempo_map_gives_the_times_it_gave() -> None:
    score = parse_text("tempo 60\nSN |x...|\ntempo 120\nSN |x...|\nrepeat 1\nat 1 BD\n")
    assert [e.time for e in score.events] == [0.0, 4.0, 6.0, 8.5]
    # the bass drum's `at` line, after the last block, adds the bar holding it (beats 12-16) at the last tempo
    assert score.beats.tolist() == [0.0, 1.0, 2.0, 3.0, 4.0, 4.5, 5.0, 5.5, 6.0, 6.5, 7.0, 7.5, 8.0, 8.5, 9.0, 9.5,
                                    10.0]


# --- limbs -----------------------------------------------------------------------------------------------------

def test_hihat_pedal_under_bass_checks_only_recent_feet(monkeypatch: pytest.MonkeyPatch) -> None:
    # every hi-hat pedal under a bass note scanned all feet notes so far: 20,000 such pairs took 36 s
    reads = {"n": 0}

    class CountingNote(limbs.Note):
        def __getattribute__(self, name: str) -> object:
            if name == "time":
                reads["n"] += 1
            return super().__getattribute__(name)

    monkeypatch.setattr(limbs, "Note", CountingNote)
    n = 1500
    events = [DrumEvent(i * 0.25, ev, 0.8) for i in range(n) for ev in (E.BASS, E.HIHATPEDAL)]
    assignment = limbs.distribute(Score(events=events), load_kit("default"))
    assert len(assignment.notes) == 2 * n and not assignment.issues
    assert reads["n"] < 50 * 2 * n
