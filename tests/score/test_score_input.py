"""Score input: GM table, MIDI files (type 0/1, tempo, running status, channels, errors), text format."""

from __future__ import annotations

import io
from pathlib import Path

import mido
import pytest

from common.kit import EventType as E
from common.score.events import DrumEvent, ScoreError, remove_duplicates
from common.score.gm import DRUM_MAP, GM_DRUM_NAMES, GM_TO_EVENT
from common.score.midi import read_midi
from common.score.text import parse_text, read_score

DATA = Path(__file__).parent.parent / "data"

# The kit sounds of the 2001 paper's table, by GM name
PAPER_TABLE = {
    35: E.BASS, 36: E.BASS, 37: E.RIM, 38: E.SNARE, 40: E.SNARE, 41: E.FLOORTOM, 42: E.HIHATCLOSED,
    43: E.FLOORTOM, 44: E.HIHATPEDAL, 45: E.MIDTOM, 46: E.HIHATOPEN, 47: E.MIDTOM, 48: E.HIGHTOM,
    49: E.CRASH, 50: E.HIGHTOM, 51: E.RIDE, 52: E.CHINA, 53: E.RIDEBELL, 55: E.SPLASH, 56: E.COWBELL,
    57: E.CRASH, 59: E.RIDE,
}  # fmt: skip


def test_every_gm_drum_note_maps_to_one_of_15_types() -> None:
    assert sorted(GM_TO_EVENT) == list(range(35, 82)) == sorted(GM_DRUM_NAMES)
    assert set(GM_TO_EVENT.values()) == set(E)
    for pitch, event in PAPER_TABLE.items():
        assert GM_TO_EVENT[pitch] == event, GM_DRUM_NAMES[pitch]


def test_td11_hihat_edge_pitches() -> None:
    assert DRUM_MAP[22] == E.HIHATCLOSED
    assert DRUM_MAP[26] == E.HIHATOPEN
    assert 21 not in DRUM_MAP and 82 not in DRUM_MAP


def _smf(type_: int, tempo_bpm: list[tuple[int, float]], notes: list[tuple[int, int, int, int]]) -> bytes:
    """A MIDI file; notes (tick, pitch, velocity, channel index); tempo changes (tick, bpm)."""
    mid = mido.MidiFile(type=type_, ticks_per_beat=480)
    meta = [(t, mido.MetaMessage("set_tempo", tempo=mido.bpm2tempo(b))) for t, b in tempo_bpm]
    msgs = [(t, mido.Message("note_on", note=p, velocity=v, channel=c)) for t, p, v, c in notes]
    msgs += [(t + 60, mido.Message("note_on", note=p, velocity=0, channel=c)) for t, p, v, c in notes]
    tracks = [meta + msgs] if type_ == 0 else [meta, msgs]
    for content in tracks:
        track = mido.MidiTrack()
        now = 0
        for t, m in sorted(content, key=lambda x: x[0]):
            track.append(m.copy(time=t - now))
            now = t
        mid.tracks.append(track)
    buf = io.BytesIO()
    mid.save(file=buf)
    return buf.getvalue()


@pytest.mark.parametrize("type_", [0, 1])
def test_midi_types_and_tempo_change(type_: int) -> None:
    data = _smf(type_, [(0, 120), (960, 60)], [(0, 36, 127, 9), (480, 38, 64, 9), (960, 42, 100, 9), (1440, 42, 0, 9)])
    score = read_midi(data)
    assert [e.event for e in score.events] == [E.BASS, E.SNARE, E.HIHATCLOSED]
    # 120 bpm for two beats (0.5 s each), then 60 bpm
    assert [round(e.time, 6) for e in score.events] == [0.0, 0.5, 1.0]
    assert score.events[0].velocity == 1.0 and 0 < score.events[1].velocity < 1
    assert score.beats[:4].round(6).tolist() == [0.0, 0.5, 1.0, 2.0]


def test_running_status_is_read() -> None:
    # hand-written type 0 file: note-ons with running status (status byte omitted)
    track = bytes([0x00, 0x99, 36, 100, 0x60, 38, 90, 0x60, 42, 80, 0x00, 0xFF, 0x2F, 0x00])
    data = b"MThd" + (6).to_bytes(4, "big") + (0).to_bytes(2, "big") + (1).to_bytes(2, "big") + (96).to_bytes(2, "big")
    data += b"MTrk" + len(track).to_bytes(4, "big") + track
    score = read_midi(data)
    assert [e.event for e in score.events] == [E.BASS, E.SNARE, E.HIHATCLOSED]
    assert score.events[2].time == pytest.approx(1.0)


def test_other_drum_channel_and_fallback() -> None:
    data = _smf(1, [(0, 120)], [(0, 36, 100, 3), (480, 38, 100, 3)])
    score = read_midi(data, drum_channels=[4])
    assert len(score.events) == 2 and not score.warnings
    fallback = read_midi(data)
    assert len(fallback.events) == 2 and "no notes on a drum channel" in fallback.warnings[0]


def test_unknown_notes_reported() -> None:
    data = _smf(1, [(0, 120)], [(0, 36, 100, 9), (480, 27, 100, 9), (960, 90, 100, 9)])
    score = read_midi(data)
    assert len(score.events) == 1
    assert sorted(n.pitch for n in score.unknown) == [27, 90]
    assert "2 notes have no drum event type" in score.warnings[0]


def test_broken_and_truncated_files_name_the_problem(tmp_path: Path) -> None:
    good = _smf(1, [(0, 120)], [(0, 36, 100, 9), (480, 38, 100, 9)])
    with pytest.raises(ScoreError, match="truncated") as cut:
        read_midi(good[:-9])
    assert "()" not in str(cut.value)  # mido's EOFError has no message: the reason is ours
    with pytest.raises(ScoreError, match="not a valid Standard MIDI File"):
        read_midi(b"RIFF0000garbage")
    path = tmp_path / "x.mid"
    path.write_bytes(good[:30])
    with pytest.raises(ScoreError, match="x.mid"):
        read_midi(path)
    with pytest.raises(ScoreError, match="no such file"):
        read_midi(tmp_path / "missing.mid")


def test_double_events_removed_velocity_kept() -> None:
    evs = [DrumEvent(0.0, E.SNARE, 0.4), DrumEvent(0.004, E.SNARE, 0.9), DrumEvent(0.2, E.SNARE, 0.5)]
    kept, removed = remove_duplicates(evs)
    assert [(e.time, e.velocity) for e in kept] == [(0.0, 0.9), (0.2, 0.5)]
    assert len(removed) == 1
    # 42 and 22 at once are one closed hi-hat
    score = read_midi(_smf(0, [(0, 120)], [(0, 42, 60, 9), (2, 22, 90, 9)]))
    assert len(score.events) == 1 and len(score.duplicates) == 1


def test_groove_files_read() -> None:
    for path in sorted(DATA.glob("groove_*.mid")):
        score = read_midi(path)
        assert score.events, path
        assert all(0.0 <= e.velocity <= 1.0 for e in score.events)
        assert all(a.time <= b.time for a, b in zip(score.events, score.events[1:], strict=False))


TEXT = """
# rock beat
tempo 120
meter 4/4
nuance legato
HH |x.x.x.x.|x.x.x.x.|
SN |..X...X.|..X...g.|
BD |x...x...|x..xx...|
ST |R.R.R.R.|R.L.R.R.|
repeat 1
at 0 CRASH 1.0 R
"""


def test_text_format() -> None:
    score = parse_text(TEXT)
    assert score.nuance is not None and score.nuance.value == "legato"
    hh = [e for e in score.events if e.event == E.HIHATCLOSED]
    assert len(hh) == 16
    assert hh[1].time == pytest.approx(0.5)  # 8 cells per 4/4 bar: eighths; x every other cell at 120 bpm
    snares = [e for e in score.events if e.event == E.SNARE]
    assert [round(e.velocity, 2) for e in snares[:4]] == [1.0, 1.0, 1.0, 0.3]
    assert score.events[-1].time == pytest.approx(8.0)  # "at" counts from the end of the blocks so far
    assert score.events[-1].event == E.CRASH
    assert any(e.event == E.CRASH and e.limb is not None for e in score.events)
    assert all(e.limb is None for e in score.events if e.event == E.BASS)


@pytest.mark.parametrize(
    "text, message",
    [
        ("HH |x.x.|\nSN |x.x|", "same"),
        ("ZZ |x.x.|", "unknown instrument"),
        ("HH |x.q.|", "unknown character"),
        ("tempo fast", "line 1"),
        ("wobble 3", "unknown directive"),
        ("repeat 2", "after a grid block"),
    ],
)
def test_text_errors(text: str, message: str) -> None:
    with pytest.raises(ScoreError, match=message):
        parse_text(text)


def test_read_score_dispatch(tmp_path: Path) -> None:
    p = tmp_path / "beat.txt"
    p.write_text("tempo 90\nBD |x...|\n", encoding="utf-8")
    assert read_score(p).events[0].event == E.BASS
    p.write_bytes(b"\xff\xfe\x00bad")
    with pytest.raises(ScoreError, match="beat.txt"):
        read_score(p)


def test_inspect_cli(capsys: pytest.CaptureFixture[str]) -> None:
    from common.score.__main__ import main

    assert main([str(DATA / "groove_drummer1_s1_220_rock-halftime_140_fill_4-4.mid"), "--algorithm", "simple"]) == 0
    out = capsys.readouterr().out
    assert "11 events" in out and "SNARE" in out and "limbs:" in out
    assert main([str(DATA / "missing.mid")]) == 1
    assert "no such file" in capsys.readouterr().err
