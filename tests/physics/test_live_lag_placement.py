"""A live physics node that fell behind has its drummer's targets trail the rig clock (``PhysicsCore.target_lag``,
tests/physics/test_live_catch_up.py). Until 6 Dec night a live note or a ``play`` arriving then was placed on the
rig clock, so it sounded late by the lag (135 ms here); the score player now places it that much earlier on the
targets' clock, and the targets keep that lag while it plays, so it sounds at its rig time. Until 7 Dec streamed
targets (/batteur/physics/target, /batteur/physics/joints) were still placed on the rig clock (a streamed stroke
struck 135 ms late); the core now places them that way too, and keeps the lag until they have played (a stroke
streamed ahead past a rest struck 135 ms early without that: the targets jumped to the rig clock in the rest).

The reproduction is deterministic: a plain (in-handler planning) live core plays a short groove, stepped by a clock
that comes back late now and then for half a second, as the node's loop does on a loaded machine.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import common.gesture.planner as planner_module
from common.character import N_DOF
from common.kit import EventType, Kit, load_kit
from common.messages import Contact, OscMessage
from common.messages.physics import CartesianTarget, JointTarget, PhysicsPosture, PhysicsReset
from common.messages.score import LiveNote, ScoreLoad, ScoreTransport
from services.physics.core import PhysicsCore
from services.physics.drummer import DrummerScene
from services.physics.node import LivePhysicsCore
from services.physics.score_player import STOP_MOVE_S
from services.physics.splice import BRAKE_S

SCORES = Path(__file__).parents[1] / "render"
LATE_STEPS = (70, 95, 120, 80, 110, 75, 105, 90)
"""Steps behind when the loop comes back late (the core simulates 50 and skips the rest)."""
LATE_FROM_S, LATE_UNTIL_S, LATE_EVERY_S = 1.6, 2.1, 0.12
"""Rig seconds the loop comes back late now and then (the groove plays from 1 s on), and how often."""
SENT_S = 2.6
"""Rig time the message arrives, seconds (the loop keeps up again by then)."""
HIGH_TOM = 48


def play_late(message: OscMessage | Sequence[OscMessage], end_s: float) -> tuple[PhysicsCore, list[Contact], float]:
    """The groove from rig time 1 s on a live core whose loop comes back late between ``LATE_FROM_S`` and
    ``LATE_UNTIL_S``; ``message`` (or each of several) handled at ``SENT_S``. Returns the core, its contacts to
    ``end_s`` and the lag its targets had when the message came (s)."""
    messages = [message] if isinstance(message, OscMessage) else list(message)
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
                for m in messages:
                    assert not core.handle(m, now_ms / 1000, ""), m  # accepted: no refusal
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


def streamed_stroke(kit: Kit, hover_from_s: float, note_s: float, speed_m_s: float = 2.0) -> list[CartesianTarget]:
    """The left stick streamed (/batteur/physics/target) over the snare from rig time ``hover_from_s``, held there
    10 cm above its hit point, and down onto it at ``note_s`` at ``speed_m_s``, rebounding (as
    services/physics/strokes.py's strokes)."""
    spec = kit.events[EventType.SNARE]
    obj = kit.object(spec.object)
    r = spec.r * obj.radius
    hit = np.array(obj.to_world((r * np.cos(spec.theta), r * np.sin(spec.theta), 0.0)))
    normal = np.array(obj.normal())
    hover = hit + 0.10 * normal
    knots = [(hover_from_s, hover, np.zeros(3)), (note_s - 0.12, hover, np.zeros(3)),
             (note_s, hit, -speed_m_s * normal), (note_s + 0.004, hit, 0.5 * speed_m_s * normal),
             (note_s + 0.15, hover, np.zeros(3))]
    return [CartesianTarget(limb="left_hand", time=t, x=p[0], y=p[1], z=p[2], vx=v[0], vy=v[1], vz=v[2])
            for t, p, v in knots]


def left_stick_on_snare(contacts: list[Contact], after_s: float) -> float:
    """Rig time (s) of the left stick's first touch of the snare after ``after_s``."""
    return min(c.time for c in contacts
               if c.instrument == "snare" and c.part.startswith("left_stick") and c.time > after_s)


@pytest.mark.slow  # 4.2-4.8 s of drummer simulation each: 5-20 s
def test_a_stroke_streamed_while_the_targets_trail_the_rig_clock_strikes_at_its_rig_time() -> None:
    """Streamed amid the groove (its left hand's last snare, 2.8 s on the trailing clock, played before it)."""
    note_s = 3.4
    core, contacts, lag = play_late(streamed_stroke(load_kit("default"), 3.0, note_s), 4.2)
    assert lag >= 0.1  # the targets trailed when it came
    hit = left_stick_on_snare(contacts, 3.1)
    assert note_s - 0.01 <= hit <= note_s + 0.03, (hit, lag)  # was note_s + lag


@pytest.mark.slow
def test_the_targets_keep_their_lag_until_a_streamed_stroke_has_played() -> None:
    """A stroke streamed for after the groove: the groove ends (3.1 s on the trailing clock) and the hand hovers
    still before the stroke, where the targets could jump to the rig clock unnoticed, which would bring the stroke
    that much early."""
    note_s = 4.2
    core, contacts, lag = play_late(streamed_stroke(load_kit("default"), 3.0, note_s), 4.8)
    assert lag >= 0.1
    hit = left_stick_on_snare(contacts, 3.1)
    assert note_s - 0.01 <= hit <= note_s + 0.03, (hit, lag)  # was note_s - lag
    assert core.target_lag == 0.0 and core.target_jumps >= 1  # back on the rig clock once it had played


def test_streamed_targets_are_queued_on_the_trailing_clock_and_hold_its_lag(drummer: PhysicsCore) -> None:
    """Cartesian and joint targets: queued ``target_lag`` earlier on the targets' clock, the lag kept until the
    last of them (targets' clock); a rig time already past is still refused (its rig time is what it asks)."""
    core, scene = drummer, drummer.scene
    assert isinstance(scene, DrummerScene)
    x, y, z = (float(v) for v in scene.rest_targets["left_hand"])

    def left(t: float) -> CartesianTarget:
        return CartesianTarget(limb="left_hand", time=t, x=x, y=y, z=z, vx=0, vy=0, vz=0)

    for k in range(1, 201):
        core.step(k / 1000)
    lag = 0.2
    assert not core.handle(left(1.0), 0.2, "")
    core.target_lag = lag  # as a live core whose loop came back late leaves it
    try:
        assert not core.handle(left(1.5), 0.2, "")
        assert not core.handle(JointTarget(time=1.4, values=tuple(scene.rest) + (0.0,) * N_DOF), 0.2, "")
        assert scene.limb_tracks["left_hand"].times == [1.0, 1.5 - lag]
        assert scene.joint_track.times == [1.4 - lag]
        assert core._lag_floor(1.5 - lag) == lag  # until the later of the two, on the targets' clock
        assert core._lag_floor(1.5 - lag + 0.001) == 0.0
        assert [o.message.ADDRESS for o in core.handle(left(0.15), 0.2, "test")] == ["/batteur/physics/rejected"]
    finally:
        core.handle(PhysicsReset(time=0.2), 0.2, "")
    assert core.target_lag == 0.0 and core._lag_floor(0.0) == 0.0


def test_a_posture_is_queued_on_the_trailing_clock_and_holds_its_lag(drummer: PhysicsCore) -> None:
    """/batteur/physics/posture (the pose editor's glide) was queued on the rig clock: it started ``target_lag``
    late. Now as streamed targets: both knots that much earlier, the lag kept until the posture is reached; a
    time already past starts at once (now, on the rig clock)."""
    core, scene = drummer, drummer.scene
    assert isinstance(scene, DrummerScene)
    lag = 0.2
    now = core.time
    core.target_lag = lag
    try:
        assert not core.handle(PhysicsPosture(time=now + 1.5, duration=0.5, values=tuple(scene.rest)), now, "")
        assert scene.joint_track.times == pytest.approx([now + 1.5 - lag, now + 2.0 - lag])  # was now + 1.5, + 2.0
        assert core._lag_floor(now + 2.0 - lag) == lag
        assert core._lag_floor(now + 2.0 - lag + 0.001) == 0.0
        assert not core.handle(PhysicsPosture(time=0.0, duration=0.0, values=tuple(scene.rest)), now, "")
        assert scene.joint_track.times[-1] == pytest.approx(now - lag)
    finally:
        core.handle(PhysicsReset(time=core.time), core.time, "")
    assert core.target_lag == 0.0 and core._lag_floor(0.0) == 0.0


@pytest.mark.slow  # 5 s of drummer simulation: 5-20 s
def test_the_targets_come_back_to_the_rig_clock_after_a_stop_not_after_the_stopped_score() -> None:
    """A ``play`` placed while the targets trail, stopped at 3.8 s: the targets jump back to the rig clock once the
    limbs rest (the stop's brake and move to the rest posture), not when the stopped groove would have ended
    (6.4 s on the targets' clock: 135 ms late until then)."""
    core, _, lag = play_late([ScoreTransport(action="play", time=3.4, position=0.0),
                              ScoreTransport(action="stop", time=3.8, position=0.0)], 5.0)
    assert lag >= 0.1
    assert core.target_lag == 0.0 and core.target_jumps >= 1  # was still the lag


def _trailing(core: PhysicsCore, lag: float) -> float:
    """``core`` with the groove loaded and its targets trailing the rig clock by ``lag`` s (as a live core whose loop
    came back late leaves them); its rig time now, s."""
    core.score_player.library = [SCORES]
    core.handle(ScoreLoad(path="short_groove.txt"), core.time, "")
    core.target_lag = lag
    return core.time


@pytest.mark.parametrize("action", ["stop", "pause", "play"])
def test_a_stop_pause_or_new_play_ends_the_lag_hold_with_what_still_plays(drummer: PhysicsCore, action: str) -> None:
    """The groove placed 0.2 s early on the targets' clock holds that lag until its end; a stop or pause cuts it
    (the hold then ends with the stop's move to the rest posture, the pause's brake), and so does a ``play`` of the
    groove's last beat (its own end): each held the lag until the cut groove's end."""
    core, lag = drummer, 0.2
    now = _trailing(core, lag)
    try:
        assert not core.handle(ScoreTransport(action="play", time=now + 1.0, position=0.0), now, "")
        groove_end = core.score_player.end_time  # on the targets' clock
        assert core._lag_floor(now) == lag
        at = now + 1.5  # rig time
        assert not core.handle(ScoreTransport(action=action, time=at, position=1.8), now, "")
        end = {"stop": at - lag + BRAKE_S + STOP_MOVE_S, "pause": at - lag + BRAKE_S,
               "play": core.score_player.end_time}[action]
        assert end < groove_end - 0.5
        assert core._lag_floor(end) == lag  # what still plays keeps it
        assert core._lag_floor(end + 0.001) == 0.0  # was the lag until groove_end
    finally:
        core.handle(PhysicsReset(time=core.time), core.time, "")


def test_a_background_play_whose_plan_fails_holds_no_lag(monkeypatch: pytest.MonkeyPatch) -> None:
    """While a ``play``'s plan is computed in the background the targets keep the lag it was placed with; once the
    plan fails (or is dropped) nothing of it plays: the hold goes with it (it stayed until the score's end)."""
    release = threading.Event()

    def failing(*args: Any, **kwargs: Any) -> Any:
        release.wait(60.0)
        raise ValueError("planner refuses")

    monkeypatch.setattr(planner_module, "plan_gestures", failing)
    core = LivePhysicsCore(planner="thread", scene="drummer", kit=load_kit("default"), grip="german",
                           pose_rate_hz=0, mode="live")
    try:
        assert core.score_player.wait_loaded(120.0)  # as the node before it listens (play: refused meanwhile)
        lag = 0.2
        now = _trailing(core, lag)
        player = core.score_player
        assert not core.handle(ScoreTransport(action="play", time=now + 1.0, position=0.0), now, "")
        assert player.busy
        assert core._lag_floor(now + 1.0) == lag  # in flight: held
        release.set()
        assert player.wait(60.0)
        player.pump(now)
        assert core.rejected == {"ScoreTransport": 1} and not player.busy
        assert core._lag_floor(now + 1.0) == 0.0  # was the lag until the score's last note
    finally:
        release.set()
        core.close()
