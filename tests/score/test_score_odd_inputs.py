"""Scores with odd but legal content, and bad ones: MIDI alien chunks, SMPTE and zero divisions, corrupt time
signatures, a MIDI file not named .mid; text repeats after a meter change, titles holding '|', notes naming
unknown instruments, a grid row of another size."""

from __future__ import annotations

from pathlib import Path

import pytest

from common.kit import EventType as E
from common.score.events import ScoreError
from common.score.midi import read_midi
from common.score.text import parse_text, read_score


def _vlq(n: int) -> bytes:
    out = [n & 0x7F]
    n >>= 7
    while n:
        out.append(0x80 | (n & 0x7F))
        n >>= 7
    return bytes(reversed(out))


def _chunk(name: bytes, body: bytes) -> bytes:
    return name + len(body).to_bytes(4, "big") + body


def _track(events: list[tuple[int, bytes]]) -> bytes:
    """An ``MTrk`` chunk of (delta ticks, message bytes), with its end-of-track."""
    return _chunk(b"MTrk", b"".join(_vlq(d) + m for d, m in events) + b"\x00\xff\x2f\x00")


def _smf(chunks: list[bytes], division: int = 480, type_: int = 1) -> bytes:
    """A Standard MIDI File of these chunks; the header counts the ``MTrk`` ones."""
    count = sum(c.startswith(b"MTrk") for c in chunks)
    header = type_.to_bytes(2, "big") + count.to_bytes(2, "big") + (division & 0xFFFF).to_bytes(2, "big")
    return _chunk(b"MThd", header) + b"".join(chunks)


BEAT = [(0, b"\x99\x24\x64"), (480, b"\x89\x24\x00"), (0, b"\x99\x26\x64"), (480, b"\x89\x26\x00")]
"""A kick at beat 0 and a snare at beat 1 on channel 10."""


def test_an_alien_chunk_between_tracks_is_skipped() -> None:
    tempo = _track([(0, b"\xff\x51\x03\x07\xa1\x20")])  # 500,000 us a beat
    plain = read_midi(_smf([tempo, _track(BEAT)]))
    alien = read_midi(_smf([tempo, _chunk(b"XFIH", b"\x00\x01\x02\x03"), _track(BEAT)]))  # was "no MTrk header"
    assert [(e.time, e.event) for e in alien.events] == [(e.time, e.event) for e in plain.events] == [
        (0.0, E.BASS), (0.5, E.SNARE)]


def test_a_file_ending_early_is_still_called_truncated() -> None:
    data = _smf([_track(BEAT), _chunk(b"XFIH", b"abcd"), _track(BEAT)])
    with pytest.raises(ScoreError, match="truncated MIDI file"):
        read_midi(data[:-6])


def test_smpte_and_zero_divisions_are_refused_in_words() -> None:
    with pytest.raises(ScoreError, match=r"SMPTE time division \(25 frames a second, 40 ticks a frame\)"):
        read_midi(_smf([_track(BEAT)], division=(0xE7 << 8) | 40))  # was "(ticks per beat -6360)"
    with pytest.raises(ScoreError, match="0 ticks per beat"):  # was called an SMPTE division
        read_midi(_smf([_track(BEAT)], division=0))


@pytest.mark.parametrize("power", [40, 255])
def test_a_time_signature_with_a_corrupt_denominator_is_ignored(power: int) -> None:
    signature = (0, b"\xff\x58\x04\x03" + bytes([power]) + b"\x18\x08")
    score = read_midi(_smf([_track([signature, *BEAT, (2 * 480, b"\x99\x24\x64")])]))  # a kick at beat 4
    # as without it (the last start: where the bar holding the file's end ends); was half a million bars of 2^-40
    # beats or less
    assert score.bar_beats.tolist() == [0, 4, 8]
    small = read_midi(_smf([_track([(0, b"\xff\x58\x04\x03\x05\x18\x08"), *BEAT, (2 * 480, b"\x99\x24\x64")])]))
    assert small.bar_beats.tolist() == [0, 0.375, 0.75, 1.125, 1.5, 1.875, 2.25, 2.625, 3, 3.375, 3.75, 4.125]  # 3/32


def test_a_repeat_after_a_meter_change_keeps_the_repeated_blocks_bars() -> None:
    score = parse_text("SN |x...|\nmeter 3/4\nrepeat 1\nBD |x..|\n")
    assert score.bar_beats.tolist() == [0, 4, 8]  # was [0, 4, 7, 8]: the repeated 4/4 bar cut in 3 + 1
    assert [e.time for e in score.events] == [0.0, 2.0, 4.0]


def test_a_title_may_hold_a_bar_line() -> None:
    score = parse_text("title Intro | Verse\nkit default|jazz\nSN |x...|\n")  # was "unknown instrument 'TITLE'"
    assert [e.event for e in score.events] == [E.SNARE]


@pytest.mark.parametrize(("text", "message"), [
    ("at 1 ZZ\n", "line 1: unknown instrument 'ZZ'"),  # was "note needs ...", the instrument not named
    ("\nat\n", "line 2: note needs '<beat> <instrument> [velocity] [L|R]'"),  # was "(list index out of range)"
    ("meter 4/0\n", "line 1: cannot read 'meter 4/0'"),  # was read as 4 beats a bar
    ("SN |x...|\nBD |x..|\n", "line 2: rows of one block must have the same bars and cells: this row has 3 cells in "
     "1 bar, the block's first row (line 1) 4 cells in 1 bar"),  # was "line 1", the row that differs not named
])
def test_bad_notes_and_meters_are_named(text: str, message: str) -> None:
    with pytest.raises(ScoreError) as err:
        parse_text(text)
    assert str(err.value).startswith(message)


def test_a_midi_file_by_another_name_is_read_as_midi(tmp_path: Path) -> None:
    path = tmp_path / "groove.kar"  # karaoke files are Standard MIDI Files; so is a file saved without a suffix
    path.write_bytes(_smf([_track(BEAT)]))
    score = read_score(path)  # was "not a text score (not UTF-8 text ...)"
    assert [(e.time, e.event) for e in score.events] == [(0.0, E.BASS), (0.5, E.SNARE)]
    text = tmp_path / "groove"
    text.write_text("SN |x...|\n")
    assert [e.event for e in read_score(text).events] == [E.SNARE]


def test_a_hand_given_for_a_foot_note_is_ignored_with_a_warning() -> None:
    from common.score.text import parse_text

    score = parse_text("tempo 120\nat 1 BD 0.5 L\nat 2 SN 0.5 R\n")
    kick, snare = score.events
    assert kick.limb is None and snare.limb is not None  # the foot plays the kick; the snare keeps its hand
    assert score.warnings == ["line 2: BD is played by a foot; the hand L is ignored"]
