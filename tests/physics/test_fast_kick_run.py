"""Runs of fast kicks. Under bass-drum strokes 0.1-0.15 s apart the IK's posture drifts stroke by stroke (the ankle
flexes toe up from about 27 to 46 degrees) and the same foot height presses the footboard less (0.64 of its travel
at the note against 0.87-1.0 for the first strokes): 16ths at 140 bpm sounded 18-20 ms late from the fifth on. A
stroke in such a run now aims ``KICK_RUN_DEPTH`` below the flat board, built up over ``KICK_RUN_STROKES`` strokes
(common/gesture/planner.py; docs/physics.md, "Kicks")."""

from __future__ import annotations

import numpy as np
import pytest

from common.gesture.plan import hermite
from common.gesture.planner import (
    KICK_RUN_DEPTH,
    KICK_RUN_GAP_S,
    KICK_RUN_NONE_S,
    KICK_RUN_RESUME_S,
    KICK_RUN_STROKES,
    plan_gestures,
)
from common.kit import EventType, Limb, load_kit
from common.score.events import DrumEvent, Score
from common.score.limbs import distribute
from tests.physics.held_pedal import onsets, played_score

SIXTEENTH_140_S = 60.0 / 140.0 / 4.0
"""16th notes at 140 bpm, seconds apart."""


def _kicks(gap_s: float, count: int, velocity: float | list[float] = 0.7) -> Score:
    """``count`` kicks ``gap_s`` apart at ``velocity`` (or each at its own)."""
    times = 0.5 + gap_s * np.arange(count)
    velocities = velocity if isinstance(velocity, list) else [velocity] * count
    return Score(events=[DrumEvent(time=float(t), event=EventType.BASS, velocity=v, pitch=36)
                         for t, v in zip(times, velocities, strict=True)],
                 beats=np.arange(0.5, float(times[-1]) + 0.5, 4 * gap_s))


def _heights_at_notes(score: Score) -> np.ndarray:
    """The planned kick foot's height over its pedal's flat target at each note time, metres."""
    kit = load_kit("default", warn=False)
    plan = plan_gestures(distribute(score, kit), kit, score)
    foot = plan.trajectories[Limb.RIGHT_FOOT]
    pos, _ = hermite(foot.times, foot.positions, foot.velocities, np.array([e.time for e in score.events]))
    return np.asarray(pos[:, 2] - kit.object("kick_pedal").position[2])


def test_a_run_of_fast_kicks_aims_deeper_stroke_by_stroke_and_eighths_do_not() -> None:
    """16ths at 140 bpm: the first two kicks at the flat board, then ever deeper up to the ``KICK_RUN_STROKES``th,
    then all ``KICK_RUN_DEPTH`` below it (from ``KICK_RUN_FULL_S`` up); eighths at 140 bpm at the flat board after the
    first (from rest: raised)."""
    heights = _heights_at_notes(_kicks(SIXTEENTH_140_S, 8))
    ramp = [-KICK_RUN_DEPTH * min(1.0, max(k - 1, 0) / (KICK_RUN_STROKES - 1)) for k in range(8)]
    assert heights == pytest.approx(ramp, abs=1e-6)
    assert heights[-1] < -0.005  # aimed well below the flat board (before: at it)
    assert _heights_at_notes(_kicks(2 * SIXTEENTH_140_S, 8))[1:] == pytest.approx(np.zeros(7), abs=1e-6)


def test_soft_kicks_in_a_run_aim_less_deep_than_loud_ones() -> None:
    """A run's deeper aim was tuned at velocity 0.7 (``KICK_RUN_SPEED``); at its full depth 16ths at velocity 0.2 met
    the head at 3.4-3.9 m/s (a lone one 1.5) and ghosts at 0.2 between accents at 0.7 as loud as the accents. Softer
    kicks in a run now aim less deep than loud ones, still below the flat board."""
    loud = _heights_at_notes(_kicks(SIXTEENTH_140_S, 8))
    soft = _heights_at_notes(_kicks(SIXTEENTH_140_S, 8, velocity=0.2))
    assert np.all(soft[3:] > loud[3:] + 0.005), f"soft {np.round(1000 * soft, 1)} loud {np.round(1000 * loud, 1)} mm"
    assert np.all(soft[3:] < -0.003)
    mixed = _heights_at_notes(_kicks(SIXTEENTH_140_S, 8, [0.7, 0.2, 0.2, 0.2] * 2))  # ghosts between accents
    ghosts = [3, 6, 7]  # ghosts after a ghost: no other deeper aim (KICK_DOUBLE_DEPTH) than the run's
    assert np.all(mixed[ghosts] > loud[ghosts] + 0.005), f"accents and ghosts {np.round(1000 * mixed, 1)} mm"
    assert mixed[4] == pytest.approx(loud[4], abs=1e-6)  # an accent keeps the whole depth


def _kicks_at(times: list[float]) -> Score:
    return Score(events=[DrumEvent(time=t, event=EventType.BASS, velocity=0.7, pitch=36) for t in times],
                 beats=np.array([0.5]))


def test_a_run_goes_on_over_one_missing_16th() -> None:
    """Six 16ths at 140 bpm, one left out, six more: the kick after the gap aims at the flat board, the next ones the
    whole ``KICK_RUN_DEPTH`` deeper at once (``KICK_RUN_RESUME_S``; restarted, they sounded 7-14 ms late). A double
    after a double one 16th later does not carry on: neither reached the whole depth."""
    g = SIXTEENTH_140_S
    heights = _heights_at_notes(_kicks_at([0.5 + g * k for k in (0, 1, 2, 3, 4, 5, 7, 8, 9, 10, 11, 12)]))
    assert heights[5] == pytest.approx(-KICK_RUN_DEPTH, abs=1e-6)
    assert heights[6] == pytest.approx(0.0, abs=1e-6)  # after the gap
    assert heights[7:] == pytest.approx(np.full(5, -KICK_RUN_DEPTH), abs=1e-6)
    assert KICK_RUN_GAP_S < 2 * g < KICK_RUN_RESUME_S
    doubles = _heights_at_notes(_kicks_at([0.5 + g * k for k in (0, 1, 3, 4, 6, 7)]))
    assert doubles == pytest.approx(np.zeros(6), abs=1e-6)
    two_left_out = _heights_at_notes(_kicks_at([0.5 + g * k for k in (0, 1, 2, 3, 4, 5, 8, 9, 10)]))
    assert two_left_out[6:] == pytest.approx([0.0, 0.0, -KICK_RUN_DEPTH / 2], abs=1e-6)  # restarted


def test_kicks_closer_than_the_run_aims_reach_keep_their_aim() -> None:
    """16ths at 180 bpm (83 ms apart, under ``KICK_RUN_NONE_S``) stay aimed at the flat board: aimed deeper, the
    drifted foot stopped the board short of the beater's contact and kicks were lost."""
    gap = 60.0 / 180.0 / 4.0
    assert gap < KICK_RUN_NONE_S
    assert _heights_at_notes(_kicks(gap, 8)) == pytest.approx(np.zeros(8), abs=1e-6)


@pytest.mark.slow  # about 3 s of simulation: 10-30 s on one core
def test_sixteen_kicks_at_140_bpm_sound_at_their_note_times() -> None:
    """The 1.75 m drummer plays 16 kicks at 140 bpm (velocity 0.7): one beater onset each, within 8 ms of its note
    (median; before: 18.4 ms late, from the fifth kick on 18-20)."""
    score = _kicks(SIXTEENTH_140_S, 16)
    strokes, contacts = played_score(score, ("kick_beater",), start_s=1.0)
    found, times = onsets(contacts), [t for t, _ in strokes]
    assert len(found) == len(times) == 16, f"kicks at {times}, beater onsets at {found}"
    errors_ms = 1000 * (np.array(found) - np.array(times))
    assert abs(float(np.median(errors_ms))) < 8.0, f"onset - note, ms: {np.round(errors_ms, 1)}"
