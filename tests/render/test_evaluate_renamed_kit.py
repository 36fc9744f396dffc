"""``batteur evaluate`` on a kit whose designer renamed the kick, its pedals and the hi-hat: each note is expected
on the object the kit's events say it sounds on, whatever the ids (a BASS note routed to a footboard was expected
on an object ``"kick"``, which such a kit does not have: every such note missed)."""

from __future__ import annotations

import numpy as np

from batteur.evaluate import Hit, evaluate_performance, expected_instrument, note_refs
from common.kit import EventType, Kit
from common.score.events import DrumEvent, Score
from tests.renamed_kits import renamed_kit


def _routed(kit: Kit, note_objects: dict[int, str]) -> Kit:
    return Kit.model_validate({**kit.model_dump(), "note_objects": {**kit.note_objects, **note_objects}})


def test_notes_are_expected_on_the_renamed_objects() -> None:
    kit = renamed_kit()
    assert expected_instrument(kit, EventType.BASS) == "bassdrum"
    assert expected_instrument(kit, EventType.BASS, 36) == "bassdrum"
    assert expected_instrument(kit, EventType.HIHATPEDAL) == "hats"  # its pedal closes the renamed hi-hat
    assert expected_instrument(kit, EventType.SNARE) == "sd"
    assert expected_instrument(_routed(kit, {36: "bd_pedal"}), EventType.BASS, 36) == "bassdrum"
    double = _routed(renamed_kit("double_pedal"), {35: "bd_pedal_2"})
    assert expected_instrument(double, EventType.BASS, 35) == "bassdrum"


def test_kicks_struck_on_the_renamed_kick_are_matched_when_a_pitch_names_its_pedal() -> None:
    kit = _routed(renamed_kit(), {36: "bd_pedal"})  # a designer's General MIDI kick routed to the footboard
    score = Score(events=[DrumEvent(t, EventType.BASS, 0.8, 36) for t in (0.0, 0.5, 1.0)], beats=np.zeros(0))
    notes = note_refs(score, kit)
    hits = [Hit(t + 0.002, "bassdrum", 2.0, "kick_beater") for t in (0.0, 0.5, 1.0)]  # physics' beater strikes
    result = evaluate_performance("renamed", notes, hits)
    assert [n.instrument for n in notes] == ["bassdrum"] * 3
    assert not result.missed and result.recall["25ms"] == 1.0
