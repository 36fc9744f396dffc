"""A ghost kick 100-120 ms after a loud one (a Groove beat's heel-toe double) sounds on time and softer: the
planner plays it as a small stroke from where the footboard is (common/gesture/planner.py ``KICK_RISE_SPEED``,
``KICK_DOUBLE_DEPTH``), not a board let up almost to its rest and braked short of the head."""

from __future__ import annotations

import numpy as np
import pytest

from common.kit import EventType
from common.score.events import DrumEvent, Score
from tests.physics.held_pedal import onset_contacts, played_score

LOUD, GHOST = 0.85, 0.07
"""Score velocities of the pair (the rock_90 Groove beat's ghost kicks are 0.07-0.12 after 0.76-0.89)."""


def _beater_onsets(gap_s: float) -> tuple[list[float], list[tuple[float, float]]]:
    """The 1.75 m drummer plays a loud kick and a ghost ``gap_s`` later; returns the notes' rig times and the
    beater's onsets (rig time, approach speed m/s)."""
    t0 = 0.5
    events = [DrumEvent(time=t0, event=EventType.BASS, velocity=LOUD, pitch=36),
              DrumEvent(time=t0 + gap_s, event=EventType.BASS, velocity=GHOST, pitch=36)]
    notes, contacts = played_score(Score(events=events, beats=np.array([t0])), ("kick_beater",), start_s=1.0)
    return [t for t, _ in notes], [(c.time, c.normal_velocity) for c in onset_contacts(contacts)]


@pytest.mark.slow  # one scene and about 3 s of simulation per gap: 10-15 s each on a loaded machine
@pytest.mark.parametrize("gap_s", [0.10, 0.12])
def test_a_ghost_kick_soon_after_a_loud_one_sounds_on_time_and_softer(gap_s: float) -> None:
    """Two beater onsets, each within 10 ms of its note, the ghost's slower than the loud kick's (before: the
    ghost sounded 21 and 19 ms late, only by following through, and in a longer render not at all)."""
    notes, onsets = _beater_onsets(gap_s)
    assert len(onsets) == 2, f"kicks at {notes}, beater onsets at {onsets}"
    for note, (heard, _) in zip(notes, onsets, strict=True):
        assert abs(heard - note) <= 0.010, f"kick at {note:.3f} s sounded at {heard:.3f} s ({gap_s} s apart)"
    assert onsets[1][1] < 0.5 * onsets[0][1], f"ghost at {onsets[1][1]:.2f} m/s after {onsets[0][1]:.2f} m/s"
