"""Score readers' rough edges: a corrupt key signature, RIFF MIDI (.rmi) files, bars past a MIDI file's end and a
text score of ``at`` lines only."""

from __future__ import annotations

import io
import struct
from pathlib import Path

import mido
import pytest

from common.kit import EventType as E
from common.score.events import Score, ScoreError
from common.score.midi import read_midi
from common.score.position import bar_beat
from common.score.text import parse_text, read_score
from tests.score.midi_files import drum_midi, riff_chunk, riff_midi, with_key


def _same_reading(a: Score, b: Score) -> None:
    assert [(e.time, e.event, e.velocity) for e in a.events] == [(e.time, e.event, e.velocity) for e in b.events]
    assert a.beats.tolist() == b.beats.tolist() and a.bar_beats.tolist() == b.bar_beats.tolist()


# --- a corrupt key signature -----------------------------------------------------------------------------------

@pytest.mark.parametrize(("key", "problem"), [
    (b"\xff\x59\x02\xee\x01", "18 flats and mode 1"),  # mido: KeySignatureError
    (b"\xff\x59\x02\x00\x2f", "0 flats and mode 47"),
    (b"\xff\x59\x01\x03", "1 byte"),  # cut short: mido's IndexError
])
def test_a_corrupt_key_signature_is_ignored_with_one_warning(key: bytes, problem: str) -> None:
    # the whole file was refused ("not a valid Standard MIDI File"); a drum score has no use for its key
    good = drum_midi([(0, 4, 4)], [0, 480, 960, 4 * 480], key=True)
    score = read_midi(with_key(good, key))
    _same_reading(score, read_midi(good))
    assert [e.event for e in score.events] == [E.SNARE] * 4
    assert len(score.warnings) == 1 and "<bytes>: a key signature" in score.warnings[0]
    assert problem in score.warnings[0] and "ignored" in score.warnings[0]


def test_corrupt_key_signatures_make_one_warning() -> None:
    good = drum_midi([(0, 4, 4)], [0, 480], key=True)
    bad = with_key(good, b"\xff\x59\x02\xee\x01" + b"\x00\xff\x59\x02\x09\x00")  # two, at tick 0
    score = read_midi(bad)
    _same_reading(score, read_midi(good))
    assert len(score.warnings) == 1 and score.warnings[0].startswith("<bytes>: 2 key signatures")


def test_reading_a_score_leaves_mido_strict_for_other_code() -> None:
    bad = with_key(drum_midi([], [0], key=True), b"\xff\x59\x02\xee\x01")
    read_midi(bad)
    with pytest.raises(mido.midifiles.meta.KeySignatureError):  # whoever else uses mido sees what it always did
        mido.MidiFile(file=io.BytesIO(bad))


# --- RIFF MIDI files ---------------------------------------------------------------------------------------------

def test_a_riff_midi_file_reads_as_the_midi_file_it_wraps(tmp_path: Path) -> None:
    smf = drum_midi([(0, 3, 4)], [0, 480, 1440, 2400])
    info = riff_chunk(b"LIST", b"INFOINAM" + struct.pack("<I", 5) + b"Beat\x00")  # 17 bytes and a pad byte before it
    _same_reading(read_midi(riff_midi(smf, info)), read_midi(smf))  # was "not a valid Standard MIDI File"
    for name in ("groove.rmi", "groove.RMI", "groove"):  # by its suffix, or by its header
        path = tmp_path / name
        path.write_bytes(riff_midi(smf, info))
        score = read_score(path)
        _same_reading(score, read_midi(smf))
        assert score.source == str(path)


@pytest.mark.parametrize(("data", "message"), [
    (riff_midi(b"", form=b"WAVE"), r"this is an audio file \(WAV\), not a score; .* batteur transcribe"),
    (riff_midi(b"", form=b"AVI "), r"not a valid Standard MIDI File \(a RIFF 'AVI ' file, not RIFF MIDI"),
    (riff_midi(b"")[:-8] + riff_chunk(b"DISP", b"abcd"), r"RIFF MIDI file without a 'data' chunk"),
    (riff_midi(drum_midi([], [0]))[:-10], r"truncated RIFF MIDI file \(its 'data' chunk"),
    (b"RIFF\x04\x00\x00\x00RMI", r"truncated RIFF file"),
    (riff_midi(b"")[:-8] + b"dat", r"truncated RIFF MIDI file"),
])
def test_a_broken_riff_midi_file_names_the_problem(data: bytes, message: str) -> None:
    with pytest.raises(ScoreError, match="<bytes>: " + message):
        read_midi(data)


def test_a_riff_file_of_another_kind_by_another_name_is_not_read_as_midi(tmp_path: Path) -> None:
    path = tmp_path / "take"  # an audio file given as the score: said to be audio, not a MIDI error
    path.write_bytes(riff_midi(b"\xff" * 16, form=b"WAVE"))
    with pytest.raises(ScoreError, match=r"this is an audio file \(WAV\), not a score; to play it, transcribe"):
        read_score(path)


# --- bars past a MIDI file's end -------------------------------------------------------------------------------

def _bar_and_beat(score: Score, beat: float, seconds_per_beat: float = 0.5) -> tuple[int, float]:
    """(bar, beat in the bar) at ``beat`` beats from the start of a score of one tempo (default 120 bpm)."""
    where = bar_beat(score, beat * seconds_per_beat)
    assert where is not None
    return where.bar, round(where.beat, 6)


@pytest.mark.parametrize(("signatures", "end", "expected"), [
    # 4/4, the file ends inside its second bar: past its end bars of 4 go on (they were bars of 1 beat)
    ([(0, 4, 4)], 5, {4.5: (1, 0.5), 5: (1, 1), 6: (1, 2), 8: (2, 0), 9: (2, 1), 12: (3, 0)}),
    # 6/8 (bars of 3 beats) ending one beat into its second bar (it went on in bars of 1 beat)
    ([(0, 6, 8)], 4, {3.5: (1, 0.5), 5: (1, 2), 6: (2, 0), 10: (3, 1)}),
    # a 3/4 signature where the file ends: bars of 3 past it (they were as long as the 4/4 bar before it)
    ([(0, 4, 4), (8 * 480, 3, 4)], 8, {7: (1, 3), 8: (2, 0), 10: (2, 2), 11: (3, 0), 15: (4, 1)}),
    # 4/4 ending on a bar line: as it was
    ([(0, 4, 4)], 8, {7: (1, 3), 8: (2, 0), 11: (2, 3), 12: (3, 0)}),
])
def test_bars_past_the_end_of_a_midi_file_are_its_last_signatures(signatures: list[tuple[int, int, int]], end: int,
                                                                   expected: dict[float, tuple[int, float]]) -> None:
    score = read_midi(drum_midi(signatures, [0, end * 480]))
    assert {beat: _bar_and_beat(score, beat) for beat in expected} == expected


# --- a text score of `at` lines only ----------------------------------------------------------------------------

def test_a_text_score_of_at_lines_has_bars_of_four_covering_its_notes() -> None:
    score = parse_text("tempo 120\nat 0 BD\nat 1 SN\nat 2 BD\nat 5.5 SN\n")
    assert [e.time for e in score.events] == [0.0, 0.5, 1.0, 2.75]  # as they were
    assert score.bar_beats.tolist() == [0, 4]  # was no bar, and one beat: no position while it played
    assert score.beats.tolist() == [0.5 * b for b in range(9)]
    assert _bar_and_beat(score, 1) == (0, 1) and _bar_and_beat(score, 5.5) == (1, 1.5)
    where = bar_beat(score, 2.75)
    assert where is not None and where.tempo_bpm == pytest.approx(120.0)


def test_a_text_score_of_at_lines_after_a_meter_has_its_bars() -> None:
    score = parse_text("tempo 60\nmeter 3/4\nat 0 BD\nat 3 SN\nat 4 SN\n")
    assert score.bar_beats.tolist() == [0, 3]
    assert score.beats.tolist() == [0, 1, 2, 3, 4, 5, 6]
    assert _bar_and_beat(score, 8, seconds_per_beat=1.0) == (2, 2)  # past the end, bars of 3 go on
