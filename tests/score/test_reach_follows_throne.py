"""The planner's reach (hands from the shoulders, feet from the hips) is measured from where the drummer sits: the
kit's throne, which a kit file or the viewer's kit editor may move (physics seats the body on it)."""

from __future__ import annotations

import numpy as np
import pytest

from common.gesture.plan import IssueReason
from common.kit import KITS_DIR, EventType, Kit, Limb, load_kit
from common.score.events import DrumEvent, Score
from common.score.limbs import SHOULDERS, distribute, shoulders, unplayable_instruments

SHIFT = (0.3, 0.0, 0.0)
"""How far the throne moves in the tests, metres: to the drummer's right."""


def _moved(kit: Kit, ids: set[str], by: tuple[float, float, float]) -> Kit:
    """``kit`` with the objects ``ids`` moved ``by`` metres."""
    objects = [o.model_copy(update={"position": tuple(p + d for p, d in zip(o.position, by, strict=True))})
               if o.id in ids else o for o in kit.objects]
    return kit.model_copy(update={"objects": objects})


def _at_the_edge() -> Kit:
    """The default kit with its china's hit point 1 m right of the right shoulder (which plays it) and its snare's
    as far left of the left one (which plays it): both in reach (the rim too)."""
    kit = load_kit("default")
    for event, object_id, side in ((EventType.CHINA, "china", 1.0), (EventType.SNARE, "snare", -1.0)):
        shoulder = np.array(SHOULDERS[Limb.RIGHT_HAND if side > 0 else Limb.LEFT_HAND])
        wanted = shoulder + np.array([side * 0.95, 0.3, 0.0])
        delta = wanted - np.array(kit.hit_point(event)[0])
        kit = _moved(kit, {object_id}, (float(delta[0]), float(delta[1]), float(delta[2])))
    return kit


def _unreachable(kit: Kit) -> list[EventType]:
    score = Score([DrumEvent(0.0, EventType.CHINA, 0.7), DrumEvent(1.0, EventType.SNARE, 0.7)])
    return [i.event for i in distribute(score, kit).issues if i.reason == IssueReason.UNREACHABLE]


def test_reach_follows_a_moved_throne() -> None:
    edge = _at_the_edge()
    assert _unreachable(edge) == [] and unplayable_instruments(edge) == []
    # the throne and the china move 0.3 m right: the china stays in reach (it was flagged from the old shoulders,
    # 1.29 m away); the snare, left where it was, is now 1.29 m from the left shoulder
    moved = _moved(edge, {"throne", "china"}, SHIFT)
    assert _unreachable(moved) == [EventType.SNARE]
    said = unplayable_instruments(moved)
    assert len(said) == 1 and said[0].startswith("snare: out of both hands' reach (SNARE 1.29 m")
    # the left-handed setup mirrors the throne too: the same notes are flagged
    assert _unreachable(moved.mirrored()) == [EventType.SNARE]
    assert [line.split(":")[0] for line in unplayable_instruments(moved.mirrored())] == ["snare"]


def test_a_kit_without_a_throne_reaches_from_the_default_seat() -> None:
    edge = _at_the_edge()
    bare = edge.model_copy(update={"objects": [o for o in edge.objects if o.kind != "throne"]})
    assert _unreachable(bare) == [] and unplayable_instruments(bare) == []


@pytest.mark.parametrize("name", sorted(p.stem for p in KITS_DIR.glob("*.yaml")))
def test_the_shipped_kits_reach_from_the_same_shoulders_and_warn_of_nothing(name: str) -> None:
    for kit in (load_kit(name), load_kit(name).mirrored()):
        assert shoulders(kit) == SHOULDERS  # bit for bit: plans and renders of the shipped kits do not change
        assert unplayable_instruments(kit) == []


def test_a_pedal_beyond_a_legs_reach_is_warned_of_and_its_notes_flagged() -> None:
    kit = load_kit("default")
    far = _moved(kit, {"hihat_pedal"}, (-1.3, 1.3, 0.0))  # 2.3 m from the throne, to the front left
    said = unplayable_instruments(far)
    assert said == ["hihat_pedal: out of the left foot's reach (HIHATPEDAL 2.28 m from the hip, a leg reaching "
                    "1.036 m): the planner drops its notes (unreachable)"]
    score = Score([DrumEvent(0.0, EventType.HIHATPEDAL, 0.7), DrumEvent(0.5, EventType.BASS, 0.7)])
    flagged = [(i.event, i.note_index) for i in distribute(score, far).issues if i.reason == IssueReason.UNREACHABLE]
    assert flagged == [(EventType.HIHATPEDAL, 0)]
    # mirrored, the right foot plays it, as far away
    mirrored = unplayable_instruments(far.mirrored())
    assert len(mirrored) == 1 and mirrored[0].startswith("hihat_pedal: out of the right foot's reach")
    # the feet follow the throne: the whole kit moved as far, nothing is out of reach
    assert unplayable_instruments(_moved(kit, {o.id for o in kit.objects}, (-1.3, 1.3, 0.0))) == []


def test_a_double_pedals_left_footboard_is_checked_from_the_left_hip() -> None:
    kit = load_kit("double_pedal")
    assert kit.left_bass_pedal is not None
    far = _moved(kit, {kit.left_bass_pedal}, (-1.5, 0.5, 0.0))
    said = unplayable_instruments(far)
    assert len(said) == 1 and said[0].startswith(f"{kit.left_bass_pedal}: out of the left foot's reach (BASS 1.")
