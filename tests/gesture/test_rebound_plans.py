"""Rebound doubles in the gesture plan: a stroke and its bounce, two close contacts from a low lift."""

from __future__ import annotations

import numpy as np
import pytest

from common.gesture.heights import stick_height
from common.gesture.plan import GesturePlan
from common.gesture.planner import BOUNCE_MIN_LIFT, bounce_height, plan_gestures
from common.kit import EventType as E
from common.kit import Limb, load_kit
from common.score.events import DrumEvent, Score
from common.score.limbs import distribute
from tests.gesture.continuity import largest_jumps

KIT = load_kit()


def _plan(events: list[tuple[float, E, float]]) -> tuple[GesturePlan, Score]:
    score = Score(sorted((DrumEvent(t, e, v) for t, e, v in events), key=lambda d: d.time))
    return plan_gestures(distribute(score, KIT, "viterbi"), KIT, score), score


ROLL = [(0.5 + 0.03 * k, E.SNARE, 0.4) for k in range(12)] + [(0.86, E.SNARE, 0.8)]
DRAG = [(0.0, E.RIDE, 0.6), (0.40, E.RIDE, 0.6), (0.42, E.SNARE, 0.3), (0.455, E.SNARE, 0.25), (0.50, E.SNARE, 0.9),
        (0.80, E.RIDE, 0.6)]


@pytest.mark.parametrize("events", [ROLL, DRAG], ids=["double_stroke_roll", "drag"])
def test_rebound_doubles_are_planned_as_stroke_and_bounce(events: list[tuple[float, E, float]]) -> None:
    plan, score = _plan(events)
    assert sorted(s.time for s in plan.strokes) == pytest.approx(sorted(t for t, _, _ in events))  # every note
    bounces = [s for s in plan.strokes if s.rebound_double]
    assert bounces
    jump_p, jump_v = largest_jumps(plan)
    assert jump_p < 1e-7 and jump_v < 1e-4
    for limb in (Limb.LEFT_HAND, Limb.RIGHT_HAND):
        strokes = plan.strokes_of(limb)
        traj = plan.trajectories[limb]
        for prev, s in zip(strokes, strokes[1:], strict=False):
            sample = traj.sample(s.time)
            np.testing.assert_allclose(sample.position, s.target, atol=1e-9)  # contact at the note time
            assert float(np.dot(sample.velocity, s.normal)) < 0  # moving into the head
            if not s.rebound_double:
                continue
            dt = s.time - prev.time
            assert dt < KIT.spec(s.event).min_time_gap and prev.object_id == s.object_id and not prev.rebound_double
            # a low bounce: below the note's own preparatory height, above the head between the two contacts
            assert BOUNCE_MIN_LIFT <= s.lift < stick_height(s.note_velocity)
            t = np.arange(prev.time + prev.contact_duration + 0.003, s.time - 0.003, 0.0005)
            pos, _ = traj.sample_many(t)
            height = (pos - s.target) @ s.normal
            assert height.min() > 0.0, f"tip {height.min() * 1000:.1f} mm into the head at {t[height.argmin()]:.3f} s"
            assert height.max() < 0.05


def test_bounce_height() -> None:
    # quarter of the mean speed times the flight time, within [BOUNCE_MIN_LIFT, cap]
    assert bounce_height(1.0, 2.0, 0.04, 0.1) == pytest.approx(0.25 * 1.5 * 0.04)
    assert bounce_height(0.0, 0.1, 0.01, 0.1) == BOUNCE_MIN_LIFT
    assert bounce_height(5.0, 5.0, 0.07, 0.02) == 0.02
