"""Reach for a single stick note with the ``simple`` and ``pairwise`` algorithms: a note beyond its preferred hand's
reach goes to the other hand when that one reaches it and is free (its last stroke at least the note's minTimeGap
before), as ``viterbi`` does; where the preferred hand reaches, or the other hand is not free, they assign as
before."""

from __future__ import annotations

import pytest

from common.kit import EventType, Limb
from common.score.events import DrumEvent, Score
from common.score.limbs import distribute
from tests.far_kits import FAR_LEFT, SMALL_M, unreachable

E = EventType


def _china_between_snares() -> Score:
    """Single china notes (0.15 s minTimeGap, preferred hand right) between snare notes (0.07 s, left), one of
    them 50 ms after a china."""
    return Score([DrumEvent(0.0, E.SNARE, 0.7), DrumEvent(0.5, E.CHINA, 0.7), DrumEvent(0.55, E.SNARE, 0.7),
                  DrumEvent(1.0, E.CHINA, 0.7), DrumEvent(1.5, E.SNARE, 0.7)])


@pytest.mark.parametrize("algorithm", ["simple", "pairwise"])
def test_a_single_far_note_goes_to_the_hand_that_reaches_it(algorithm: str) -> None:
    """The small drummer's right hand cannot reach the china, the left one can and is free: the left hand plays
    both chinas and the right the snare 50 ms after the first (was: the chinas on the right hand, the first dropped
    unreachable, the left hand busy with that snare, the second moved to the left hand by the check)."""
    small = distribute(_china_between_snares(), FAR_LEFT, algorithm, height_m=SMALL_M)
    assert unreachable(small.issues) == []
    assert [(n.time, n.event, n.limb) for n in small.notes] == [
        (0.0, E.SNARE, Limb.LEFT_HAND), (0.5, E.CHINA, Limb.LEFT_HAND), (0.55, E.SNARE, Limb.RIGHT_HAND),
        (1.0, E.CHINA, Limb.LEFT_HAND), (1.5, E.SNARE, Limb.LEFT_HAND)]
    assert small.issues == []


@pytest.mark.parametrize("algorithm", ["simple", "pairwise"])
def test_a_single_note_both_hands_reach_keeps_its_hand(algorithm: str) -> None:
    """The default drummer reaches the china with either hand: the chinas on the right hand, the preferred one, and
    the snare after the first on the left, as before."""
    default = distribute(_china_between_snares(), FAR_LEFT, algorithm)
    assert [(n.event, n.limb) for n in default.notes] == [
        (E.SNARE, Limb.LEFT_HAND), (E.CHINA, Limb.RIGHT_HAND), (E.SNARE, Limb.LEFT_HAND),
        (E.CHINA, Limb.RIGHT_HAND), (E.SNARE, Limb.LEFT_HAND)]
    assert unreachable(default.issues) == []


@pytest.mark.parametrize("algorithm", ["simple", "pairwise"])
def test_a_single_far_note_the_other_hand_is_not_free_for_stays_and_is_flagged(algorithm: str) -> None:
    """A china 50 ms after a left-hand snare: the left hand is not free (under the china's 0.15 s minTimeGap), so
    the china keeps its preferred right hand, beyond its reach, and the check drops it flagged unreachable; the
    left hand is not handed a stroke too fast for it."""
    score = Score([DrumEvent(0.45, E.SNARE, 0.7), DrumEvent(0.5, E.CHINA, 0.7), DrumEvent(1.0, E.SNARE, 0.7)])
    small = distribute(score, FAR_LEFT, algorithm, height_m=SMALL_M)
    assert unreachable(small.issues) == [(1, "dropped")]
    assert [(n.event, n.limb) for n in small.notes] == [(E.SNARE, Limb.LEFT_HAND), (E.SNARE, Limb.LEFT_HAND)]
    assert [i for i in small.issues if i.reason.value == "too_fast"] == []
