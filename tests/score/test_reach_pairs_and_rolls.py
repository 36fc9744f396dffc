"""Reach in every hand assignment: a simultaneous pair split by the ``simple`` and ``pairwise`` algorithms, and a roll
sticking (RLRL...), give a note beyond one hand's reach to the other hand when that one reaches it (and, in a roll,
is free then), as ``viterbi`` does; where both hands reach, they assign as before."""

from __future__ import annotations

import pytest

from common.gesture.plan import IssueAction, IssueReason
from common.kit import EventType, Limb
from common.score.events import DrumEvent, Score
from common.score.limbs import _distance_m, distribute, hand_reach, shoulders
from tests.far_kits import FAR_LEFT, SMALL_M, unreachable

E = EventType
def test_the_far_kit_is_what_the_tests_need() -> None:
    china = FAR_LEFT.hit_point(E.CHINA)[0]
    at = shoulders(FAR_LEFT, SMALL_M)
    assert _distance_m(china, at[Limb.LEFT_HAND]) < hand_reach(SMALL_M) < _distance_m(china, at[Limb.RIGHT_HAND])
    assert max(_distance_m(china, s) for s in shoulders(FAR_LEFT).values()) < hand_reach()
    assert FAR_LEFT.spec(E.CHINA).preferred == Limb.RIGHT_HAND and FAR_LEFT.stale_pairs() == {}


@pytest.mark.parametrize("algorithm", ["simple", "pairwise", "viterbi"])
def test_a_pair_gives_the_far_note_to_the_hand_that_reaches_it(algorithm: str) -> None:
    """China and snare at once: the pair preference wants the china on the right hand, which cannot reach it; the
    left hand takes it and the right the snare (was, with simple and pairwise: china on the right, then dropped
    unreachable, the left hand being busy with the snare)."""
    score = Score([DrumEvent(0.0, E.SNARE, 0.7), DrumEvent(0.5, E.CHINA, 0.7), DrumEvent(0.5, E.SNARE, 0.7),
                   DrumEvent(1.0, E.SNARE, 0.7)])
    small = distribute(score, FAR_LEFT, algorithm, height_m=SMALL_M)
    assert unreachable(small.issues) == []
    assert [(n.time, n.event, n.limb) for n in small.notes if n.time == 0.5] == [
        (0.5, E.CHINA, Limb.LEFT_HAND), (0.5, E.SNARE, Limb.RIGHT_HAND)]
    assert len(small.notes) == 4


@pytest.mark.parametrize("algorithm", ["simple", "pairwise"])
def test_a_pair_both_hands_reach_splits_as_before(algorithm: str) -> None:
    """The default drummer reaches the china with either hand: the pair preference puts it on the right hand (the
    arms crossed, flagged and played: the kit's preference is its own)."""
    score = Score([DrumEvent(0.5, E.CHINA, 0.7), DrumEvent(0.5, E.SNARE, 0.7)])
    default = distribute(score, FAR_LEFT, algorithm)
    assert {n.event: n.limb for n in default.notes} == {E.CHINA: Limb.RIGHT_HAND, E.SNARE: Limb.LEFT_HAND}
    assert unreachable(default.issues) == []


def _roll_then_snare() -> Score:
    """Five china notes 0.2 s apart (a roll: under twice the china's 0.15 s minTimeGap; single sticking RLRLR, the
    right hand leading), then a snare 50 ms after the last."""
    return Score([DrumEvent(0.2 * k, E.CHINA, 0.7) for k in range(5)] + [DrumEvent(0.85, E.SNARE, 0.7)])


@pytest.mark.parametrize("algorithm", ["simple", "pairwise", "viterbi"])
def test_a_roll_gives_a_far_note_to_the_other_hand_when_it_is_free(algorithm: str) -> None:
    """The right hand's notes of the roll go to the left hand, which plays them all as full strokes (0.2 s apart),
    and the right hand, free, takes the snare (was: the last china forced on the right hand, the snare on the left
    50 ms after it, and the china dropped unreachable with no free hand)."""
    small = distribute(_roll_then_snare(), FAR_LEFT, algorithm, "single", height_m=SMALL_M)
    assert unreachable(small.issues) == []
    assert [(n.event, n.limb) for n in small.notes] == [(E.CHINA, Limb.LEFT_HAND)] * 5 + [(E.SNARE, Limb.RIGHT_HAND)]
    assert [i for i in small.issues if i.reason == IssueReason.TOO_FAST] == []


def test_a_roll_note_the_other_hand_is_not_free_for_stays_and_is_flagged() -> None:
    """China notes 0.1 s apart (RLRL): the left hand takes the first right-hand note, its own second note then a
    rebound double (0.1 s, under the china's 0.15 s minTimeGap); after that bounce it has no time for the third
    note, which stays on the right hand, beyond its reach, and the check flags it unreachable and drops it (was:
    the first note too left on the right hand, for the check to move)."""
    score = Score([DrumEvent(0.1 * k, E.CHINA, 0.7) for k in range(4)])
    small = distribute(score, FAR_LEFT, "viterbi", "single", height_m=SMALL_M)
    assert [(round(n.time, 6), n.limb, n.rebound) for n in small.notes] == [
        (0.0, Limb.LEFT_HAND, False), (0.1, Limb.LEFT_HAND, True), (0.3, Limb.LEFT_HAND, False)]
    assert unreachable(small.issues) == [(2, IssueAction.DROPPED)]
    assert "the left hand is busy" in next(i.detail for i in small.issues if i.reason == IssueReason.UNREACHABLE)


@pytest.mark.parametrize("sticking", ["single", "double", "paradiddle"])
def test_a_roll_both_hands_reach_keeps_its_sticking(sticking: str) -> None:
    """The default drummer reaches the china with either hand: the pattern's hands, as before."""
    score = Score([DrumEvent(0.1 * k, E.CHINA, 0.7) for k in range(8)])
    pattern = {"single": "RLRLRLRL", "double": "RRLLRRLL", "paradiddle": "RLRRLRLL"}[sticking]
    hands = [n.limb for n in distribute(score, FAR_LEFT, "viterbi", sticking).notes]
    assert hands == [Limb.RIGHT_HAND if c == "R" else Limb.LEFT_HAND for c in pattern]
