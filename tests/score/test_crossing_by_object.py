"""The ``crossing`` check judges a note that strikes another object than its event type's own (a ``note_objects``
pitch: the double-pedal kit's second ride, pitch 59, out to the left) by where the hit points are: the kit's pair
preference is between event types on their own objects (RIDE,SNARE: the right hand on the ride, out to the right).
A 1.40 m drummer's left hand on that ride with the right on the snare was flagged ``crossing``; the arms do not
cross there. The pair preference still judges notes on their own objects."""

from __future__ import annotations

from common.gesture.plan import IssueReason
from common.kit import EventType, Limb, load_kit
from common.score.events import DrumEvent, Score
from common.score.limbs import distribute

E = EventType
RIDE2 = 59
DOUBLE_PEDAL = load_kit("double_pedal")


def _crossings(score: Score, height_m: float = 1.75) -> list[int]:
    """Indices of the notes ``distribute`` flags ``crossing`` on the double-pedal kit."""
    assignment = distribute(score, DOUBLE_PEDAL, height_m=height_m)
    return [i.note_index for i in assignment.issues if i.reason == IssueReason.CROSSING]


def _groove() -> Score:
    """Eighths on the second ride, snare on beats 2 and 4 (at 120 bpm)."""
    events = [DrumEvent(k * 0.25, E.RIDE, 0.7, pitch=RIDE2) for k in range(8)]
    events += [DrumEvent(t, E.SNARE, 0.7) for t in (0.5, 1.5)]
    return Score(sorted(events, key=lambda e: e.time))


def test_the_left_hand_on_the_second_ride_beside_the_snare_is_no_crossing() -> None:
    assignment = distribute(_groove(), DOUBLE_PEDAL, height_m=1.4)
    at_once = [(n.event, n.limb) for n in assignment.notes if n.time == 0.5]
    assert sorted(at_once) == [(E.RIDE, Limb.LEFT_HAND), (E.SNARE, Limb.RIGHT_HAND)]  # the ride is out to the left
    assert _crossings(_groove(), 1.4) == []  # was: both snare beats flagged, left hand on RIDE


def test_a_real_crossing_is_still_flagged() -> None:
    # on their own objects the pair preference judges: the left hand on the ride, the right on the hi-hat
    by_preference = Score([DrumEvent(0.0, E.RIDE, 0.7, limb=Limb.LEFT_HAND), DrumEvent(0.0, E.HIHATCLOSED, 0.7)])
    assert _crossings(by_preference) == [1]
    # the right hand on the second ride, out to the left, over the left hand on the snare: crossed where they are
    over = Score([DrumEvent(0.0, E.SNARE, 0.7, limb=Limb.LEFT_HAND),
                  DrumEvent(0.0, E.RIDE, 0.7, pitch=RIDE2, limb=Limb.RIGHT_HAND)])
    assert _crossings(over) == [1]
    # the left hand there, beside the snare: not crossed, whatever RIDE,SNARE says of the first ride
    beside = Score([DrumEvent(0.0, E.SNARE, 0.7, limb=Limb.RIGHT_HAND),
                    DrumEvent(0.0, E.RIDE, 0.7, pitch=RIDE2, limb=Limb.LEFT_HAND)])
    assert _crossings(beside) == []
