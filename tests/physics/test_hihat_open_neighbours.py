"""An open hi-hat note's pedal window and its neighbours (``_open_hihat``).

Among closed ones at 16ths, the foot opens the pedal after the previous closed stroke and closes it for the next
one: its lift of 0.18 s before to 0.32 s after the note took them in (at 120 bpm the closed notes either side were
played at openness 0.19 and 0.40, open; at 100 bpm 0.03, half, and 0.22, open).
An open note followed by a pedal chick (open on the "and", closed by the foot on the beat): the foot lifts for the
open note and comes down into the chick; it skipped the lift when a pedal stroke was within 0.48 s before to 0.63 s
after the open note, which played closed."""

from __future__ import annotations

import numpy as np
import pytest

from common.kit import EventType, load_kit
from common.score.events import DrumEvent, Score
from services.interaction.detect import ImpactOnset, Segmenter
from services.interaction.features import ZoneConfig
from tests.physics.held_pedal import onset_contacts, played_score

STICKS = ("right_stick_tip", "left_stick_tip")
PATTERN = "CCCOCCC"
"""Closed x3, open, closed x3."""


@pytest.mark.slow  # one drummer scene, about 2.5 s of simulation: 4-10 s
@pytest.mark.parametrize("gap_s", [0.15, 0.125], ids=["16ths at 100 bpm", "16ths at 120 bpm"])
def test_an_open_16th_is_open_and_the_closed_16ths_around_it_closed(gap_s: float) -> None:
    events = [DrumEvent(time=0.5 + gap_s * k, event=EventType.HIHATOPEN if ch == "O" else EventType.HIHATCLOSED,
                        velocity=0.7, pitch=46 if ch == "O" else 42) for k, ch in enumerate(PATTERN)]
    notes, contacts = played_score(Score(events=events, beats=np.array([0.5, 1.0])), STICKS, start_s=1.0)
    onsets = onset_contacts([c for c in contacts if c.instrument == "hihat"])
    assert len(onsets) == len(notes), f"notes at {notes}, stick onsets on the hi-hat at {[c.time for c in onsets]}"
    zones = ZoneConfig()
    for t, event in notes:
        c = min(onsets, key=lambda c: abs(c.time - t))
        if event == EventType.HIHATOPEN:
            assert c.openness >= zones.hihat_open_from, f"open note at {t:.3f} s: openness {c.openness:.3f}"
        else:
            assert 0.0 <= c.openness < zones.hihat_half_from, f"closed note at {t:.3f} s: openness {c.openness:.3f}"


@pytest.mark.slow  # one drummer scene, about 2.5-3.5 s of simulation
@pytest.mark.parametrize("gap_s", [0.25, 0.5], ids=["eighths at 120 bpm", "quarters at 120 bpm"])
def test_an_open_note_closed_by_a_pedal_chick_is_open_and_the_chick_on_time(gap_s: float) -> None:
    E = EventType
    seq = [(E.HIHATCLOSED, 42), (E.HIHATOPEN, 46), (E.HIHATPEDAL, 44), (E.HIHATCLOSED, 42)]
    events = [DrumEvent(time=0.5 + gap_s * k, event=e, velocity=0.7, pitch=p) for k, (e, p) in enumerate(seq)]
    notes, contacts = played_score(Score(events=events, beats=np.array([0.5, 1.0])),
                                   (*STICKS, "hihat_top", "hihat_rattle"), start_s=1.0)
    hat = [c for c in contacts if c.instrument == "hihat"]
    sticks = onset_contacts([c for c in hat if c.part in STICKS])
    zones = ZoneConfig()
    seg = Segmenter(load_kit("default", warn=False))
    impacts = [e.impact for c in hat for e in seg.contact(c, c.time) if isinstance(e, ImpactOnset)]
    chicks = [i for i in impacts if i.part == "hihat_top"]
    for t, event in notes:
        if event == E.HIHATPEDAL:  # the plates closed by the foot at the note: an impact (interaction's chick)
            near = [round(i.time, 3) for i in chicks if abs(i.time - t) < 0.1]
            assert near and all(abs(x - t) <= 0.01 for x in near), f"pedal note at {t:.3f} s: chicks at {near}"
            continue
        c = min(sticks, key=lambda c: abs(c.time - t))
        if event == E.HIHATOPEN:
            assert c.openness >= zones.hihat_open_from, f"open note at {t:.3f} s: openness {c.openness:.3f}"
        else:
            assert 0.0 <= c.openness < zones.hihat_half_from, f"closed note at {t:.3f} s: openness {c.openness:.3f}"
    assert len(chicks) == 1, f"chicks at {[(round(i.time, 3), i.velocity) for i in chicks]}"
