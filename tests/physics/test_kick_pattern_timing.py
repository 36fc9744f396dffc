"""Kicks after the foot's previous one. The footboard under a foot held at its rest height settles for most of a
second after a stroke (pressed 0.10 of its travel 0.1 s after a kick at velocity 0.4, 0.18 at 0.7 s), and so does
the height where the beater meets the head: aimed at the flat board, kicks 1 s after the one before sounded 9, 5
and 3 ms early at velocity 0.3, 0.7 and 1.0, the time the foot takes over the contact rise at their speeds
(``kick_contact_rise``), as lone kicks from rest did; 0.25 and 0.5 s after it they sounded within 3 ms. A kick is
now raised by its gap's share of the way from ``KICK_RAISE_FROM_S`` to ``KICK_REST_GAP_S`` (common/gesture/planner.py;
docs/physics.md, "Kicks")."""

from __future__ import annotations

import numpy as np
import pytest

from common.gesture.heights import foot_speed
from common.gesture.plan import hermite
from common.gesture.planner import KICK_RAISE_FROM_S, KICK_REST_GAP_S, kick_contact_rise, plan_gestures
from common.kit import EventType, Limb, load_kit
from common.score.events import DrumEvent, Score
from common.score.limbs import distribute
from tests.physics.held_pedal import onsets, played_score

ONSET_GAP_S = 0.015
"""Contacts of the beater closer than this belong to one onset."""
STEP_S = 0.001
"""The physics step: an onset is known to within it, seconds."""
GAPS_S = (0.25, 0.5, 1.0)
"""Kicks this far apart at 120 bpm: a sixteenth, an eighth, a quarter note's double."""
VELOCITIES = (0.3, 0.7, 1.0)


def _pattern() -> list[tuple[float, float]]:
    """A first kick (0.5 s, velocity 0.7), then for each gap every velocity, that gap after the kick before."""
    notes = [(0.5, 0.7)]
    for gap in GAPS_S:
        for velocity in VELOCITIES:
            notes.append((notes[-1][0] + gap, velocity))
    return notes


def _score(notes: list[tuple[float, float]]) -> Score:
    return Score(events=[DrumEvent(time=t, event=EventType.BASS, velocity=v, pitch=36) for t, v in notes],
                 beats=np.arange(notes[0][0], notes[-1][0] + 0.25, 0.5))


def test_a_kick_is_raised_by_the_share_of_the_board_come_back_since_the_feet_last_kick() -> None:
    """The planned foot at each kick's note time: at the flat board up to ``KICK_RAISE_FROM_S`` after the kick
    before, ``kick_contact_rise`` above it from ``KICK_REST_GAP_S`` on, in between the gap's share of the way (before:
    at the flat board until 1.5 s)."""
    kit = load_kit("default", warn=False)
    gaps = (0.25, KICK_RAISE_FROM_S, (KICK_RAISE_FROM_S + KICK_REST_GAP_S) / 2, KICK_REST_GAP_S, 1.2)
    notes = [(0.5, 0.7)]
    for gap in gaps:
        notes.append((notes[-1][0] + gap, 0.7))
    score = _score(notes)
    plan = plan_gestures(distribute(score, kit), kit, score)
    foot = plan.trajectories[Limb.RIGHT_FOOT]
    pos, _ = hermite(foot.times, foot.positions, foot.velocities, np.array([t for t, _ in notes]))
    heights = pos[:, 2] - kit.object("kick_pedal").position[2]
    rise = kick_contact_rise()
    assert heights == pytest.approx([rise, 0.0, 0.0, rise / 2, rise, rise], abs=1e-6)


@pytest.mark.slow  # about 6 s of simulation: 25-40 s on a loaded machine
def test_kicks_a_sixteenth_an_eighth_and_a_quarter_after_another_sound_at_their_note_times() -> None:
    """The 1.75 m drummer plays kicks 0.25, 0.5 and 1.0 s apart at velocity 0.3, 0.7 and 1.0: one beater onset
    each, within half the time the foot takes over the contact rise at the stroke's speed (the lone kick's bound,
    tests/physics/test_kick_contact_timing.py) plus two steps (the onset's and the note's place between steps).
    Before, the kicks 1 s after another sounded 9 (velocity 0.3) and 5 ms (0.7) early: the foot's whole time over
    the contact rise."""
    notes = _pattern()
    strokes, contacts = played_score(_score(notes), ("kick_beater",), start_s=1.0)
    found, times = onsets(contacts, ONSET_GAP_S), [t for t, _ in strokes]
    assert len(found) == len(times) == len(notes), f"kicks at {times}, beater onsets at {found}"
    late = [(round(n, 3), v, round(1000 * (o - t), 1))
            for (n, v), t, o in zip(notes, times, found, strict=True)
            if abs(o - t) > 0.5 * kick_contact_rise() / foot_speed(v) + 2 * STEP_S]
    assert not late, f"kicks (note time s, velocity, onset - note ms) off their note times: {late}"
