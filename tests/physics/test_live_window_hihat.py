"""Several live notes in a row around open hi-hats: the hi-hat foot's track is a whole re-plan's.

A live note re-plans a window of the performance (tests/physics/test_live_window.py). An open hi-hat lifts the
hi-hat pedal (the left foot) around it, and a live note can change those lifts without the foot playing a note in
its window: here a crash 7 ms before one of the score's open hi-hats takes the right hand, the planner drops the open
hi-hat, and the pedal must close 0.25 s earlier than the queued plan has it. Four live notes (a hi-hat pedal, a
snare, an open hi-hat and that crash), each sent 0.4 s ahead, 0.5 s apart, on the 55 s Groove file; after each one
every limb's track, sampled every millisecond to the end of the performance, and its strikes must be those a
re-plan of the whole rest gives. The crash's window is planned again, widened to the foot's next note (not with the
whole rest), in the handler and in the live node's background plans.

The score plays from its position :data:`FROM_S` (rig time ``1 + FROM_S``, each note at the rig time it has when
played from the start): the notes' windows reach back ``CONTEXT_S`` (2 s) before their splice, 17.4 s at the
earliest, and the drummer plays the groove from 15 s on, so every window, the queued plan it re-joins and the whole
re-plans are of a drummer playing the groove, as from the start. Simulating the 14 s before it took about two thirds
of these tests' CPU time.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from common.gesture.plan import hermite
from common.messages.score import LiveNote
from services.physics.drummer import DrummerScene
from services.physics.score_player import ScorePlayer
from tests.physics.test_live_window import live_playing, offline_playing

LEAD_S = 0.4
"""Each live note sounds this long after it is sent, s."""
NOTES = [(19.05, 44), (19.55, 38), (20.05, 46), (20.55, 49)]
"""(rig time sent s, GM pitch): the score's open hi-hats at 20.624, 20.704 and 20.957 s chain one pedal lift (to
21.077 s); the crash at 20.95 s drops the one at 20.957 s (7 ms after, same hand), so the lift ends at 20.824 s.
The pedal note at 19.45 s gives the foot a note in the last window's context (its next one is at 25.8 s)."""
AGREE_M = 1e-6
AGREE_M_S = 1e-6
"""Window and whole re-plan tracks agree within these (as tests/physics/test_live_window.py)."""

FROM_S = 14.0
"""The score plays from this position, s (at rig time 1 s later): 3.4 s of groove before the first window's context."""

Knots = tuple[np.ndarray, np.ndarray, np.ndarray, list[tuple[float, float, str, float]]]


def _play(whole: bool) -> tuple[list[dict[str, Knots]], list[int], list[Any], dict[str, Any]]:
    """Play the score and send NOTES; the tracks (knots, strikes) right after each note's plan and how many notes
    that plan had, the performance's notes at the end and the player's status. ``whole``: every live note
    re-planned with the whole rest."""
    physics, runner, _, control = offline_playing(FROM_S)
    player = physics.score_player
    scene = physics.scene
    assert isinstance(scene, DrummerScene)
    states: list[dict[str, Knots]] = []
    planned: list[int] = []
    for at, pitch in NOTES:
        runner.run_until(at)
        control.send(LiveNote(time=at + LEAD_S, pitch=pitch, velocity=100, channel=10), "physics")
        states.append({name: (np.array(track.times), np.array(track.values), np.array(track.velocities),
                              [(s.time, s.bottom, s.instrument, s.speed) for s in track.strikes])
                       for name, track in scene.limb_tracks.items()})
        assert player.last_plan is not None
        planned.append(len(player.last_plan.strokes))
    events = [(e.time, e.event, e.limb) for e in player.events]
    status = player.status()
    physics.close()
    assert physics.rejected == {}
    return states, planned, events, status


def test_live_notes_in_a_row_leave_the_hi_hat_foot_as_a_whole_re_plan_does(monkeypatch: pytest.MonkeyPatch) -> None:
    window, planned, window_events, status = _play(whole=False)
    assert status["late_notes"] == 0
    # every note planned with a window of the 400 notes left, not all of them: the crash's is planned again with
    # its window widened to the hi-hat foot's next note (at 25.8 s), where the foot re-joins its queued plan
    assert all(n < 100 for n in planned), planned
    assert status["live_window_misses"] == 1
    monkeypatch.setattr(ScorePlayer, "_window_end", lambda self, new, t_s, widen=False: math.inf)
    whole, _, whole_events, _ = _play(whole=True)
    assert window_events == whole_events
    for (at, pitch), mine, theirs in zip(NOTES, window, whole, strict=True):
        for name, (t2, p2, v2, strikes2) in theirs.items():
            t1, p1, v1, strikes1 = mine[name]
            times = np.arange(at, max(t1[-1], t2[-1]) + 0.1, 0.001)
            (q1, w1), (q2, w2) = hermite(t1, p1, v1, times), hermite(t2, p2, v2, times)
            dp, dv = np.abs(q1 - q2).max(axis=1), np.abs(w1 - w2).max(axis=1)
            k = int(np.argmax(dp))
            assert dp.max() <= AGREE_M and dv.max() <= AGREE_M_S, (
                f"after the note {pitch} sent at {at} s, {name}: {dp.max():.2e} m at {times[k]:.3f} s")
            assert strikes1 == strikes2, name


def test_the_live_node_plans_the_crash_again_with_a_widened_window_and_closes_the_hi_hat() -> None:
    """The live node (background plans): the crash's window does not re-join (the pedal must close earlier and the
    foot has no note in the window), so it is planned again with the window widened to the foot's next note, not
    with the whole rest; the crash sounds and the pedal is down again by 21.06 s (the queued lift held it up)."""
    physics, runner, recorder, control = live_playing(FROM_S)
    player = physics.score_player
    for at, pitch in NOTES:
        runner.run_until(at)
        control.send(LiveNote(time=at + LEAD_S, pitch=pitch, velocity=100, channel=10), "physics")
        while player.busy:  # each plan (and the crash's second) spliced at the step after it is ready
            assert player.wait(60.0)
            runner.run_until(runner.now + 0.002)
    scene = physics.scene
    assert isinstance(scene, DrummerScene)
    foot = scene.limb_tracks["left_foot"]
    lifted = float(foot.sample(21.062)[0][2] - foot.sample(21.5)[0][2])
    runner.run_until(21.3)
    physics.close()
    # the play and each note's plan spliced once
    assert player.window_misses == 1 and player.plans == 1 + len(NOTES) and player.late_notes == 0
    assert physics.rejected == {}
    assert player.last_plan is not None and len(player.last_plan.strokes) < 100  # a window, not the 400 notes left
    assert abs(lifted) < 1e-3, f"the hi-hat pedal is still {lifted * 100:.1f} cm up at 21.062 s"
    crash = NOTES[-1][0] + LEAD_S
    assert [i for i in recorder.impacts.sorted() if i.instrument == "crash" and abs(i.time - crash) <= 0.005]
