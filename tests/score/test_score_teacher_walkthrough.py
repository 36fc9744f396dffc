"""What a music teacher writing small scores met: a score saved as UTF-16 (Notepad's "Unicode") called an MP3, a
`meter N/D` whose D was ignored (6/8 played its eighths as quarters, unlike a MIDI file in 6/8), `at 0 SN L`
refused, a score without a tempo line played at 120 without a word, a text score named .mid, instrument typos
without the names meant, a row without its first `|` called a directive, sticking over foot notes ignored
silently, a lone ST row adding a bar, uneven bars not named, an empty file read as a score of nothing, and a type 2
MIDI file's track taking the tempo of the track before it."""

from __future__ import annotations

import io
from pathlib import Path

import mido
import pytest

from common.kit import EventType as E
from common.kit import Limb
from common.score.events import ScoreError
from common.score.midi import read_midi
from common.score.position import bar_beat
from common.score.text import parse_text, read_score
from tests.score.midi_files import drum_midi

GROOVE = "tempo 100\nHH |x.x.x.x.|\nSN |..x...x.|\n"


def _timing(score: object) -> list[tuple[float, E, float]]:
    return [(round(e.time, 9), e.event, e.velocity) for e in score.events]  # type: ignore[attr-defined]


@pytest.mark.parametrize("encoding", ["utf-16", "utf-16-le", "utf-16-be", "utf-32", "utf-32-be"])
def test_a_score_saved_as_utf16_or_utf32_with_its_byte_order_mark_is_read(tmp_path: Path, encoding: str) -> None:
    plain = tmp_path / "plain.txt"
    plain.write_text(GROOVE)
    path = tmp_path / "notepad.txt"
    mark = {"utf-16-le": b"\xff\xfe", "utf-16-be": b"\xfe\xff", "utf-32-be": b"\x00\x00\xfe\xff"}.get(encoding, b"")
    path.write_bytes(mark + GROOVE.replace("\n", "\r\n").encode(encoding))  # as Notepad writes it
    # was "this is an audio file (MP3) ... transcribe it first" (FF FE) or "not UTF-8 text" (FE FF)
    assert _timing(read_score(path)) == _timing(read_score(plain))


def test_utf16_that_is_not_text_after_its_mark_says_so(tmp_path: Path) -> None:
    path = tmp_path / "cut.txt"
    path.write_bytes(b"\xff\xfe" + "tempo 100\n".encode("utf-16-le") + b"\x00\xd8")  # a lone surrogate
    with pytest.raises(ScoreError) as refused:
        read_score(path)
    message = str(refused.value)
    assert "UTF-16" in message and "save it as UTF-8" in message and "audio" not in message


def _six_eight_midi() -> bytes:
    return drum_midi([(0, 6, 8)], [240 * k for k in range(12)])  # 120 bpm, eighths over two bars of 6/8


def test_a_meter_of_eighths_plays_as_a_midi_file_in_the_same_meter_and_tempo() -> None:
    text = parse_text("tempo 120\nmeter 6/8\nSN |xxxxxx|xxxxxx|\n")
    midi = read_midi(_six_eight_midi())
    assert [e.time for e in text.events] == pytest.approx([e.time for e in midi.events])  # 0.25 s apart (was 0.5)
    assert text.events[1].time == pytest.approx(0.25)
    shared = min(len(text.beats), len(midi.beats))  # the MIDI file ends at its last note, the text score its bar
    assert shared >= 6 and list(text.beats[:shared]) == pytest.approx(list(midi.beats[:shared]))  # quarter notes
    for t in (0.1, 0.75, 1.6, 2.9):  # the position the view shows: bars of 3 quarter notes in both
        a, b = bar_beat(text, t), bar_beat(midi, t)
        assert a is not None and b is not None and (a.bar, a.beat) == (b.bar, pytest.approx(b.beat))


def test_the_unit_of_a_meter_counts() -> None:
    eighths = parse_text("tempo 100\nmeter 3/8\nSN |xxx|\nmeter 3/4\nSN |xxx|\n")
    times = [e.time for e in eighths.events]
    assert times == pytest.approx([0.0, 0.3, 0.6, 0.9, 1.5, 2.1])  # 3/8 and 3/4 timed alike: 0.6 s cells in both
    assert list(eighths.bar_beats)[:2] == pytest.approx([0.0, 1.5])  # a bar of 3/8: 1.5 quarter notes
    # a fractional meter of eighths: bars of 1.25 quarter notes; `rest` and `at` count quarter notes
    frac = parse_text("tempo 60\nmeter 2.5/8\nSN |x....|\nrest 1\nat 0.5 BD\n")
    assert list(frac.bar_beats)[:2] == pytest.approx([0.0, 1.25])
    assert [(e.time, e.event) for e in frac.events] == [(0.0, E.SNARE), (pytest.approx(2.75), E.BASS)]


def test_a_quarter_note_meter_is_as_it_was() -> None:
    score = parse_text("tempo 120\nmeter 3/4\nSN |x.x.x.|\nrepeat 1\nat 1 BD\nrest\n")
    assert [e.time for e in score.events] == pytest.approx([0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.5])
    assert list(score.bar_beats) == pytest.approx([0.0, 3.0, 6.0])


def test_an_at_line_may_give_the_hand_without_the_velocity() -> None:
    score = parse_text("tempo 100\nat 0 SN L\nat 1 SN R\nat 2 SN 0.5 L\n")  # `at 0 SN L` was refused
    assert [(e.velocity, e.limb) for e in score.events] == [
        (0.7, Limb.LEFT_HAND), (0.7, Limb.RIGHT_HAND), (0.5, Limb.LEFT_HAND)]
    assert parse_text("tempo 100\nat 0 BD L\n").warnings == ["line 2: BD is played by a foot; the hand L is ignored"]


def test_a_score_without_a_tempo_line_says_it_plays_at_120() -> None:
    score = parse_text("HH |x.x.x.x.|\n")
    assert score.events[1].time == pytest.approx(0.5)  # a quarter note at 120
    assert score.warnings == ["no tempo line: played at 120 beats (quarter notes) per minute"]
    assert parse_text("tempo 120\nHH |x.x.x.x.|\n").warnings == []


def test_a_text_score_named_mid_is_called_one(tmp_path: Path) -> None:
    for name, data in (("groove.mid", GROOVE.encode()), ("notepad.mid", GROOVE.encode("utf-16"))):
        path = tmp_path / name
        path.write_bytes(data)
        for read in (read_score, read_midi):
            with pytest.raises(ScoreError) as refused:
                read(path)  # was "not a valid Standard MIDI File (OSError: MThd not found ...)"
            assert str(refused.value).startswith(f"{path}: this looks like a text score, not a MIDI file; rename "
                                                 f"it .txt")


def test_a_file_that_is_not_midi_says_so_without_pythons_class_name() -> None:
    with pytest.raises(ScoreError) as refused:
        read_midi(b"\x01\x02\x03 not a MIDI file at all")
    assert str(refused.value) == "<bytes>: not a valid Standard MIDI File (MThd not found. Probably not a MIDI file)"


@pytest.mark.parametrize(("row", "near"), [
    ("SNRE |..x...x.|", "did you mean SNARE or SN?"),
    ("HIHAT |x.x.x.x.|", "did you mean HIHATOPEN, HIHATCLOSED, HIHATPEDAL"),
    ("TOM1 |x.x.x.x.|", "did you mean T1"),
    ("HH: |x.x.x.x.|", "did you mean HH?"),
    ("at 0 SNRE", "did you mean SNARE or SN?"),
])
def test_an_unknown_instrument_names_the_nearest_and_where_the_list_is(row: str, near: str) -> None:
    with pytest.raises(ScoreError) as refused:
        parse_text(f"tempo 100\n{row}\n")
    message = str(refused.value)
    assert message.startswith(f"line 2: unknown instrument {row.split()[-1 if row.startswith('at') else 0]!r}: ")
    assert near in message and "docs/score-format.md" in message


def test_a_row_without_its_first_bar_line_says_so() -> None:
    with pytest.raises(ScoreError) as refused:
        parse_text("tempo 100\nHH x.x.x.x.\n")  # was "unknown directive 'HH'"
    assert str(refused.value) == "line 2: a grid row needs its bars between '|': write HH |x.x.x.x.|"
    with pytest.raises(ScoreError, match="unknown directive 'kick'"):
        parse_text("kick snare\n")  # words, not cells: not a row


def test_sticking_over_foot_notes_warns_as_an_at_line_does() -> None:
    score = parse_text("tempo 100\nBD |xxxx|\nSN |.x..|\nST |RLRL|\n")
    assert [e.limb for e in score.events if e.event is E.BASS] == [None] * 4
    assert score.warnings == ["line 4: ST cells 1, 3-4: BD is played by a foot; the hands there are ignored"]
    assert parse_text("tempo 100\nSN |xxxx|\nBD |x...|\nST |RLRL|\n").warnings == []  # a stick note in each


def test_a_sticking_row_alone_in_its_block_is_refused() -> None:
    with pytest.raises(ScoreError) as refused:
        parse_text("tempo 100\nSN |x.x.|\n\nST |RLRL|\n")  # added a silent bar
    assert str(refused.value).startswith("line 4: the ST row has no instrument rows in its block")


def test_uneven_bars_name_the_bar() -> None:
    with pytest.raises(ScoreError) as refused:
        parse_text("tempo 100\nHH |x.x.x.x.|x.x.x.|\n")  # was "(got [6, 8])"
    assert str(refused.value) == ("line 2: bar 2 has 6 cells, bar 1 has 8 (the bars of one row have the same number "
                                  "of cells)")


def test_an_empty_text_score_is_called_empty(tmp_path: Path) -> None:
    empty = tmp_path / "empty.txt"
    empty.write_bytes(b"")
    with pytest.raises(ScoreError) as refused:
        read_score(empty)  # was a score of 0 events, without a word
    assert str(refused.value) == f"{empty}: the file is empty (0 bytes)"
    blank = tmp_path / "blank.txt"
    blank.write_text("# nothing yet\ntempo 100\n")
    assert read_score(blank).warnings == [f"{blank}: no drum events"]  # as a MIDI file's


def test_each_track_of_a_type_2_file_starts_at_120_bpm_unless_it_sets_its_own() -> None:
    mid = mido.MidiFile(type=2, ticks_per_beat=480)
    for tempo in (1_000_000, None, 250_000):  # 60 bpm, none, 240 bpm
        track = mido.MidiTrack()
        if tempo is not None:
            track.append(mido.MetaMessage("set_tempo", tempo=tempo))
        for k in range(2):
            track.append(mido.Message("note_on", channel=9, note=38, velocity=100, time=480 * (k > 0)))
        track.append(mido.MetaMessage("end_of_track", time=480))
        mid.tracks.append(track)
    data = io.BytesIO()
    mid.save(file=data)
    score = read_midi(data.getvalue())
    # two beats a track: 2 s at 60 bpm; then 1 s at 120 (was 2 s, at the first track's 60); then 0.5 s at 240
    assert [e.time for e in score.events] == pytest.approx([0.0, 1.0, 2.0, 2.5, 3.0, 3.25])


@pytest.mark.parametrize("meter", ["1/8", "3/16"])
def test_a_score_shorter_than_a_beat_still_has_bar_positions(meter: str) -> None:
    """With D counted, one bar of 1/8 is half a beat: the beats stopped at beat 0 and no note had a bar position
    (the view showed none, the head nodded once)."""
    score = parse_text(f"tempo 60\nmeter {meter}\nSN |{'x' * int(meter.split('/')[0])}|\n")
    assert list(score.beats) == [0.0, 1.0]
    assert all(bar_beat(score, e.time) is not None and bar_beat(score, e.time).bar == 0 for e in score.events)


@pytest.mark.parametrize("meter", ["3/128", "0.001/64", "1/1000000"])
def test_a_meter_of_bars_shorter_than_a_64th_note_is_refused(meter: str) -> None:
    """Bars of a few 1e-12 beats passed (80,004 bar starts for 5 beats), below the grid's own tolerances."""
    with pytest.raises(ScoreError, match="D 1 to 64"):
        parse_text(f"meter {meter}\nSN |x|\n")
