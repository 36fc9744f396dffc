"""A small (and a tall) drummer's kick foot: the planner's foot heights were measured with the 1.75 m drummer;
physics raises or lowers the bass-drum foot's aim and rest by the height (services/physics/drummer.py
``KICK_FOOT_AIM_PER_M``), so a 1.4 m drummer's soft kicks reach the head and a 2.0 m drummer's do not sound early,
and a tall drummer's feet do not knock their pedals down when the scene starts."""

from __future__ import annotations

import pytest

from common.kit import EventType
from tests.physics.held_pedal import onsets, played_pedal_notes

PEDAL_PARTS = ("kick_beater", "hihat_top")


def _pedal_onsets(height_m: float, velocities: tuple[float, ...]) -> tuple[list[float], dict[str, list[float]]]:
    """A ``height_m`` tall drummer plays single kicks at ``velocities`` from the scene's start (rest posture) on;
    returns the notes' rig times and the onsets of the beater and the hi-hat's top plate."""
    notes, contacts = played_pedal_notes(height_m, EventType.BASS, 36, velocities, PEDAL_PARTS, start_s=1.0)
    return notes, {part: onsets([c for c in contacts if c.part == part]) for part in PEDAL_PARTS}


@pytest.mark.slow  # two scenes and about 3 s of simulation each: 30-35 s on a loaded machine
@pytest.mark.parametrize("height_m", [1.4, 2.0])
def test_soft_kicks_sound_once_and_on_time_for_a_small_or_tall_drummer(height_m: float) -> None:
    """Soft kicks (score velocities 0.1-0.3, as a Groove beat's ghost notes): one beater onset each within 25 ms
    of its note, and no other pedal sound from the start on (before: at 1.4 m the 0.1 kick did not sound, the
    board pressed 0.91 where the beater meets the head at 0.95; at 2.0 m it sounded 32 ms early, and the feet,
    their toes in the footboards at rest, knocked the kick and the hi-hat at the scene's start)."""
    velocities = (0.1, 0.2, 0.3)
    notes, onsets = _pedal_onsets(height_m, velocities)
    assert len(notes) == len(velocities)
    assert onsets["hihat_top"] == [], f"the hi-hat sounded at {onsets['hihat_top']} s with no pedal note"
    beats = onsets["kick_beater"]
    assert len(beats) == len(notes), f"{height_m} m drummer: kicks at {notes}, beater onsets at {beats}"
    for note, heard in zip(notes, beats, strict=True):
        assert abs(heard - note) <= 0.025, f"{height_m} m drummer: kick at {note:.3f} s sounded at {heard:.3f} s"
