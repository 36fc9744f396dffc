"""The physics node reads live notes (``/batteur/score/note``) with its ``--drum-map``, as it reads its MIDI scores:
the node gives its score player the MIDI reading options (``ScorePlayer.midi``), and until 7 Dec the
live path kept General MIDI's map whatever they said (a Roland kit's tom 3 rim, 58, played a china; a pitch only
the map names was refused as unknown). Driven offline through the core's message handler (rig times as sent)."""

from __future__ import annotations

from common.kit import EventType
from common.messages.physics import PhysicsRejected
from common.messages.score import LiveNote
from common.score.midi_options import midi_setting_kwargs
from services.physics.core import PhysicsCore

SENDER = "127.0.0.1:9"


def test_live_notes_are_read_with_the_node_drum_map(tmp_path) -> None:  # type: ignore[no-untyped-def]
    path = tmp_path / "pads.toml"
    path.write_text('[notes]\n100 = "FLOORTOM"\n', encoding="utf-8")
    core = PhysicsCore(scene="drummer", grip="german", pose_rate_hz=0)
    try:
        player = core.score_player
        out = core.handle(LiveNote(time=1.0, pitch=100, velocity=100, channel=10), 0.0, SENDER)
        refused = [o.message.reason for o in out if isinstance(o.message, PhysicsRejected)]
        assert refused and "pitch 100 has no drum event type" in refused[0]  # General MIDI's map: no drum
        player.midi = midi_setting_kwargs("", str(path), False)  # as the node sets its --drum-map
        out = core.handle(LiveNote(time=1.5, pitch=100, velocity=100, channel=10), 0.0, SENDER)
        assert not [o for o in out if isinstance(o.message, PhysicsRejected)]
        assert [(e.event, e.pitch) for e in player.events] == [(EventType.FLOORTOM, 43)]
        assert player.unknown_pitches == 1 and player.midi["note_map"] == {100: 43}
    finally:
        core.close()
