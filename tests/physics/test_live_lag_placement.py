"""A live physics node that fell behind has its drummer's targets trail the rig clock (``PhysicsCore.target_lag``,
tests/physics/test_live_catch_up.py). Until 6 Dec night a live note or a ``play`` arriving then was placed on the
rig clock, so it sounded late by the lag (135 ms here); the score player now places it that much earlier on the
targets' clock, and the targets keep that lag while it plays, so it sounds at its rig time.

The reproduction is deterministic: a plain (in-handler planning) live core plays a short groove, stepped by a clock
that comes back late now and then for half a second, as the node's loop does on a loaded machine.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from common.kit import load_kit
from common.messages import Contact, OscMessage
from common.messages.score import LiveNote, ScoreLoad, ScoreTransport
from services.physics.core import PhysicsCore

SCORES = Path(__file__).parents[1] / "render"
LATE_STEPS = (70, 95, 120, 80, 110, 75, 105, 90)
"""Steps behind when the loop comes back late (the core simulates 50 and skips the rest)."""
LATE_FROM_S, LATE_UNTIL_S, LATE_EVERY_S = 1.6, 2.1, 0.12
"""Rig seconds the loop comes back late now and then (the groove plays from 1 s on), and how often."""
SENT_S = 2.6
"""Rig time the message arrives, seconds (the loop keeps up again by then)."""
HIGH_TOM = 48


def play_late(message: OscMessage, end_s: float) -> tuple[PhysicsCore, list[Contact], float]:
    """The groove from rig time 1 s on a live core whose loop comes back late between ``LATE_FROM_S`` and
    ``LATE_UNTIL_S``; ``message`` handled at ``SENT_S``. Returns the core, its contacts to ``end_s`` and the lag
    its targets had when the message came (s)."""
    core = PhysicsCore(scene="drummer", kit=load_kit("default"), grip="german", pose_rate_hz=0, mode="live")
    core.score_player.library = [SCORES]
    core.handle(ScoreLoad(path="short_groove.txt"), 0.0, "")
    core.handle(ScoreTransport(action="play", time=1.0, position=0.0), 0.0, "")
    contacts: list[Contact] = []
    now_ms, k, next_late_s, lag = 0, 0, LATE_FROM_S, -1.0
    try:
        while now_ms < end_s * 1000:
            now_ms += 1
            if LATE_FROM_S * 1000 <= now_ms < LATE_UNTIL_S * 1000 and now_ms >= next_late_s * 1000:
                now_ms += LATE_STEPS[k % len(LATE_STEPS)] - 1
                k += 1
                next_late_s = now_ms / 1000 + LATE_EVERY_S
            if lag < 0.0 and now_ms >= SENT_S * 1000:
                lag = core.target_lag
                assert not core.handle(message, now_ms / 1000, "")  # accepted: no refusal
            contacts += [o.message for o in core.step(now_ms / 1000) if isinstance(o.message, Contact)]
    finally:
        core.close()
    return core, contacts, lag


def first_touch(contacts: list[Contact], instrument: str, after_s: float) -> float:
    """Rig time (s) of the first contact with ``instrument`` after ``after_s``."""
    return min(c.time for c in contacts if c.instrument == instrument and c.time > after_s)


@pytest.mark.slow  # 4-6.5 s of drummer simulation: 5-20 s
def test_a_live_note_while_the_targets_trail_the_rig_clock_sounds_at_its_rig_time() -> None:
    note_s = 3.25  # between the groove's strokes on the trailing clock (a note 65 ms after one is too fast)
    core, contacts, lag = play_late(LiveNote(time=note_s, pitch=HIGH_TOM, velocity=100, channel=10), 6.5)
    hit = first_touch(contacts, "hightom", SENT_S)
    assert lag >= 0.1  # the targets trailed when it came
    assert note_s - 0.01 <= hit <= note_s + 0.03, (hit, lag)  # was note_s + lag
    assert core.target_lag == 0.0 and core.target_jumps >= 1  # back on the rig clock once the groove ended (5.8 s)


@pytest.mark.slow
def test_a_play_while_the_targets_trail_the_rig_clock_starts_at_its_rig_time() -> None:
    """The groove again from its start (a snare on its second beat, 0.6 s in) at rig time 3.4 s."""
    start_s = 3.4
    core, contacts, lag = play_late(ScoreTransport(action="play", time=start_s, position=0.0), 4.2)
    assert lag >= 0.1
    hit = first_touch(contacts, "snare", start_s + 0.3)
    assert start_s + 0.6 - 0.01 <= hit <= start_s + 0.6 + 0.03, (hit, lag)  # was 135 ms later
