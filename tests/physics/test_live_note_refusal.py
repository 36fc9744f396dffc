"""A live note whose window cannot be spliced (a limb's track has no room for the window's knots) is refused: its
sender is told why (the track bound, MAX_TRACK_KNOTS), it is counted, and no track changes.

The window's span check (``splice_window``: each limb's span checked before any track changes) is where the refusal
comes from; the core is driven offline through its handler (rig times as sent; no wall clock).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from common.messages.physics import PhysicsRejected
from common.messages.score import LiveNote, ScoreLoad, ScoreTransport
from services.physics import score_player as score_player_module
from services.physics.core import PhysicsCore

MIDI = Path(__file__).parents[1] / "data" / "groove_drummer6_s3_1_rock_90_beat_4-4.mid"  # 439 notes, 55 s
SENDER = "127.0.0.1:9"
HIGH_TOM = 48


def test_a_live_note_whose_window_has_no_room_is_refused_with_the_reason(monkeypatch: pytest.MonkeyPatch) -> None:
    core = PhysicsCore(scene="drummer", grip="german", pose_rate_hz=0)
    try:
        player = core.score_player
        player.library = [MIDI.parent]
        core.handle(ScoreLoad(path=MIDI.name), 0.0, SENDER)
        core.handle(ScoreTransport(action="play", time=1.0, position=0.0), 0.0, SENDER)
        while core.time < 4.0:
            core.step(core.time + 0.001)
        windows: list[Any] = []
        splice_window = score_player_module.splice_window

        def recorded(*args: Any, **kwargs: Any) -> None:
            windows.append(args)
            splice_window(*args, **kwargs)

        monkeypatch.setattr(score_player_module, "splice_window", recorded)
        tracks = core.scene.limb_tracks  # type: ignore[attr-defined]
        for track in tracks.values():
            monkeypatch.setattr(track, "max_knots", len(track))  # full: a window adds its splice knot
        queued = {limb: list(track.times) for limb, track in tracks.items()}
        out = core.handle(LiveNote(time=4.6, pitch=HIGH_TOM, velocity=100, channel=10), 4.0, SENDER)
        replies = [(o.to, o.message.address, o.message.reason) for o in out if isinstance(o.message, PhysicsRejected)]
        assert len(windows) == 1 and player.window_misses == 0  # refused by the window's splice, not re-planned
        assert [(to, address) for to, address, _ in replies] == [(SENDER, LiveNote.ADDRESS)]
        assert "MAX_TRACK_KNOTS" in replies[0][2] and "the queued knots are kept" in replies[0][2]
        assert core.rejected == {"LiveNote": 1} and player.errors == {"LiveNote": 1}
        assert {limb: list(track.times) for limb, track in tracks.items()} == queued
    finally:
        core.close()
