"""An open hi-hat note is played on a hi-hat opened as a drummer opens it: the foot lets the pedal up most of the
way (``PlannerConfig.hihat_open_lift``), so the stick meets plates about 10 mm apart (the default kit's rest opening:
15 mm). Lifted 3 cm, they were 2.7 mm apart, barely off a closed hat. The higher lift must not keep the hat open
longer: the closed notes after it are still closed, and the plates close without a pedal chick the score lacks."""

from __future__ import annotations

import numpy as np
import pytest

from common.kit import EventType, load_kit
from common.messages import Contact
from common.score.events import DrumEvent, Score
from services.interaction.features import ZoneConfig
from services.physics.kitbodies import HIHAT_MAX_GAP_M
from tests.physics.held_pedal import onset_contacts, played_score

STICKS = ("right_stick_tip", "left_stick_tip")
NOTES = [(EventType.HIHATCLOSED, 42), (EventType.HIHATCLOSED, 42), (EventType.HIHATOPEN, 46),
         (EventType.HIHATCLOSED, 42), (EventType.HIHATCLOSED, 42)]
"""Eighths at 120 bpm (0.25 s apart), the third open: the closed note after it comes as soon as a groove has it."""
OPEN_GAP_MIN_M = 0.008
"""The open note's plates at least this far apart (at 7 cm: 10.3 mm; at 3 cm: 2.7 mm)."""


@pytest.fixture(scope="module")
def played() -> tuple[list[tuple[float, EventType]], list[Contact]]:
    """The 1.75 m drummer plays NOTES; the notes' rig times and events, and the hi-hat's contacts (sticks, plates)."""
    events = [DrumEvent(time=0.5 + 0.25 * k, event=e, velocity=0.7, pitch=pitch) for k, (e, pitch) in enumerate(NOTES)]
    notes, contacts = played_score(Score(events=events, beats=np.array([0.5, 1.0])),
                                   (*STICKS, "hihat_top", "hihat_rattle"), start_s=1.0)
    return notes, [c for c in contacts if c.instrument == "hihat"]


@pytest.mark.slow  # one drummer scene, about 2.5 s of simulation: 4-10 s
def test_an_open_note_meets_plates_well_apart_and_the_closed_notes_after_it_closed(played: tuple) -> None:
    notes, contacts = played
    onsets = onset_contacts([c for c in contacts if c.part in STICKS])
    assert len(onsets) == len(notes), f"notes at {notes}, stick onsets on the hi-hat at {[c.time for c in onsets]}"
    rest = load_kit("default", warn=False).object("hihat").opening
    zones = ZoneConfig()
    for t, event in notes:
        c = min(onsets, key=lambda c: abs(c.time - t))
        gap = c.openness * HIHAT_MAX_GAP_M
        if event == EventType.HIHATOPEN:
            assert gap >= OPEN_GAP_MIN_M, f"open note at {t:.3f} s: plates {gap * 1e3:.1f} mm apart"
            # the foot keeps the pedal: the footboard short of its stop, where the plates stand at the rest opening
            assert c.openness < 0.9 * rest, f"open note at {t:.3f} s: openness {c.openness:.3f} (rest {rest})"
        else:
            assert 0.0 <= c.openness < zones.hihat_half_from, f"closed note at {t:.3f} s: openness {c.openness:.3f}"


@pytest.mark.slow
def test_the_plates_close_after_the_open_note_without_a_pedal_chick(played: tuple) -> None:
    """The foot lets the plates down slowly: they meet as a stroke's rattle or below interaction's slowest chick
    (``hihat_top`` under 0.1 m/s), never as a pedal note (at 9 cm falling evenly over 0.2 s: 0.106 m/s)."""
    _, contacts = played
    chicks = [c for c in onset_contacts([c for c in contacts if c.part == "hihat_top"]) if c.normal_velocity >= 0.1]
    assert chicks == [], f"pedal chicks at {[(round(c.time, 3), round(c.normal_velocity, 3)) for c in chicks]}"
