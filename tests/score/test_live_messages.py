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
