"""The planner's reach follows the drummer's height (de Leva's segments scale with stature): a note at the edge of
the default 1.75 m drummer's reach is flagged for a 1.40 m one; the default height keeps every number as it was."""

from __future__ import annotations

import numpy as np

from common.gesture.plan import IssueReason
from common.kit import EventType, Kit, Limb, load_kit
from common.score.events import DrumEvent, Score
from common.score.limbs import (
    FOOT_REACH,
    HIPS,
    REACH,
    SHOULDERS,
    distribute,
    foot_reach,
    hand_reach,
    hips,
    shoulders,
    unplayable_instruments,
)
from tests.far_kits import china_at


def _unreachable(kit: Kit, height_m: float | None = None) -> list[EventType]:
    score = Score([DrumEvent(0.0, EventType.CHINA, 0.7), DrumEvent(1.0, EventType.SNARE, 0.7)])
    assignment = distribute(score, kit) if height_m is None else distribute(score, kit, height_m=height_m)
    return [i.event for i in assignment.issues if i.reason == IssueReason.UNREACHABLE and i.event is not None]


def test_a_note_at_the_edge_of_the_default_reach_is_flagged_for_a_small_drummer() -> None:
    edge = china_at(load_kit("default"), 1.10)  # within the default 1.15 m
    assert _unreachable(edge) == [] and _unreachable(edge, 1.75) == []
    assert _unreachable(edge, 1.40) == [EventType.CHINA]
    assert _unreachable(edge, 2.0) == []
    said = unplayable_instruments(edge, 1.40)
    assert len(said) == 1 and said[0].startswith("china: out of both hands' reach") and "1.02 m" in said[0]
    assert unplayable_instruments(edge) == []
    # a tall drummer reaches further: a china 1.20 m away is flagged for the default one only
    far = china_at(load_kit("default"), 1.20)
    assert _unreachable(far) == [EventType.CHINA] and _unreachable(far, 2.0) == []


def test_the_default_height_keeps_the_reach_bit_for_bit() -> None:
    kit = load_kit("default")
    assert shoulders(kit, 1.75) == SHOULDERS and hips(kit, 1.75) == HIPS
    assert hand_reach() == REACH and foot_reach() == FOOT_REACH
    small = hips(kit, 1.40)  # physics seats a 1.40 m body's hips 0.072 m above the seat, 0.04 m forward
    assert np.allclose(small[Limb.RIGHT_FOOT], (0.072, 0.04, 0.52 + 0.072))
    assert foot_reach(1.40) < FOOT_REACH and hand_reach(1.40) < REACH < hand_reach(2.0)
