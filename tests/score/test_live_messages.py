"""Live notes over OSC and the score control messages."""

from __future__ import annotations

from common.kit import EventType
from common.messages import decode, encode
from common.messages.score import GestureStyle, KitSelect, LiveNote, ScoreLoad, ScoreTransport, TempoScale
from common.score.live import LiveNotes


def test_score_messages_roundtrip() -> None:
    messages = [
        LiveNote(time=12.25, pitch=38, velocity=100, channel=10),
        ScoreLoad(path="/tmp/groove.mid"),
        ScoreTransport(action="play", time=3.5, position=0.0),
        GestureStyle(grip="french", nuance="vertical_accent", algorithm="viterbi", sticking="paradiddle"),
        TempoScale(factor=1.5),
        KitSelect(kit="double_pedal"),
    ]
    for m in messages:
        decoded = decode(encode(m))
        assert not decoded.errors
        assert decoded.messages == [m]


def test_out_of_range_live_note_is_dropped_not_raised() -> None:
    from common.messages import encode_raw

    decoded = decode(encode_raw("/batteur/score/note", [1, 0.0, 200, 100, 10]))
    assert not decoded.messages and decoded.errors[0].reason.value == "out_of_range"


def test_live_notes_map_count_unknown_and_doubles() -> None:
    live = LiveNotes()
    snare = live.accept(LiveNote(time=1.0, pitch=38, velocity=127, channel=10))
    assert snare is not None and snare.event == EventType.SNARE and snare.velocity == 1.0
    assert live.accept(LiveNote(time=1.004, pitch=40, velocity=90, channel=10)) is None  # double snare
    assert live.duplicates == 1
    assert live.accept(LiveNote(time=1.1, pitch=26, velocity=64, channel=10)).event == EventType.HIHATOPEN  # type: ignore[union-attr]
    assert live.accept(LiveNote(time=1.2, pitch=100, velocity=64, channel=10)) is None
    assert [n.pitch for n in live.unknown] == [100]
    assert live.accept(LiveNote(time=1.3, pitch=36, velocity=0, channel=10)) is None  # note-off


def test_live_notes_take_the_note_map_as_a_midi_file_does(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """``--drum-map``: a live note's pitch is the sender's layout, mapped to the General MIDI pitch it plays before
    the drum map, as the MIDI reader maps a file's (live notes were read as General MIDI whatever the map). The event
    carries the mapped pitch (a kit's ``note_objects`` choose by it); an unknown note keeps the pitch sent."""
    from common.score.midi_notes import ROLAND_TD, load_drum_map

    plain, roland = LiveNotes(), LiveNotes(note_map=ROLAND_TD)
    tom3_rim = LiveNote(time=1.0, pitch=58, velocity=100, channel=10)  # General MIDI's vibraslap
    assert plain.accept(tom3_rim).event == EventType.CHINA  # type: ignore[union-attr]
    played = roland.accept(tom3_rim)
    assert played is not None and (played.event, played.pitch) == (EventType.FLOORTOM, 43)
    crash2_edge = roland.accept(LiveNote(time=1.1, pitch=52, velocity=100, channel=10))
    assert crash2_edge is not None and (crash2_edge.event, crash2_edge.pitch) == (EventType.CRASH, 57)
    path = tmp_path / "hats.json"
    path.write_text('{"notes": {"25": "HIHATOPEN", "100": 38}}', encoding="utf-8")
    mine = LiveNotes(note_map=load_drum_map(str(path)))
    hat = mine.accept(LiveNote(time=2.0, pitch=25, velocity=64, channel=10))
    assert hat is not None and (hat.event, hat.pitch) == (EventType.HIHATOPEN, 46)
    assert mine.accept(LiveNote(time=2.1, pitch=100, velocity=64, channel=10)).event == EventType.SNARE  # type: ignore[union-attr]
    assert mine.accept(LiveNote(time=2.2, pitch=101, velocity=64, channel=10)) is None
    assert [n.pitch for n in mine.unknown] == [101]
    assert plain.accept(LiveNote(time=2.3, pitch=100, velocity=64, channel=10)) is None  # unmapped: unknown
