"""Limb rules (hi-hat, pedal substitution, two hands) and the three hand-assignment algorithms."""

from __future__ import annotations

import pytest

from common.gesture.plan import IssueAction, IssueReason
from common.kit import EventType as E
from common.kit import Limb, load_kit
from common.score.events import DrumEvent, Score
from common.score.hands import HandNote, Sticking, assign_hands
from common.score.limbs import distribute

KIT = load_kit()
LH, RH, LF, RF = Limb.LEFT_HAND, Limb.RIGHT_HAND, Limb.LEFT_FOOT, Limb.RIGHT_FOOT


def _score(*events: tuple[float, E] | tuple[float, E, float]) -> Score:
    return Score([DrumEvent(e[0], e[1], e[2] if len(e) > 2 else 0.7) for e in events])  # type: ignore[misc]


def _limbs(score: Score, algorithm: str = "viterbi") -> list[tuple[str, Limb]]:
    return [(n.event.value, n.limb) for n in distribute(score, KIT, algorithm).notes]


def test_one_stick_hihat_at_a_time_with_the_pedal_under_it() -> None:
    a = distribute(_score((0.0, E.HIHATOPEN, 0.5), (0.0, E.HIHATCLOSED, 0.9), (0.008, E.HIHATPEDAL)), KIT)
    kept = {n.event: n.limb for n in a.notes}
    # the louder stick hi-hat is kept; the foot closes the hi-hat under it, as Groove MIDI drummers do
    assert set(kept) == {E.HIHATCLOSED, E.HIHATPEDAL}
    assert kept[E.HIHATPEDAL] == LF and kept[E.HIHATCLOSED] in (LH, RH)
    assert [(i.event, i.reason, i.action) for i in a.issues] == [
        (E.HIHATOPEN, IssueReason.HIHAT_CONFLICT, IssueAction.DROPPED)
    ]
    # on the mirrored kit the hi-hat foot is the right one, beside the left foot's bass drum
    mirrored = distribute(_score((0.0, E.HIHATCLOSED), (0.008, E.HIHATPEDAL), (0.0, E.BASS)), load_kit("left_handed"))
    assert {n.event: n.limb for n in mirrored.notes} == {E.HIHATCLOSED: LH, E.HIHATPEDAL: RF, E.BASS: LF}
    assert not mirrored.issues
    # two pedal chicks at once are one: the louder stays
    b = distribute(_score((0.0, E.HIHATPEDAL, 0.3), (0.005, E.HIHATPEDAL, 0.6)), KIT)
    assert [(n.event, n.velocity) for n in b.notes] == [(E.HIHATPEDAL, 0.6)]
    assert [i.reason for i in b.issues] == [IssueReason.HIHAT_CONFLICT]
    # a pedal under a stick hi-hat among three stick notes: the stick hi-hat is given up, the pedal sounds it
    group = ((0.0, E.HIHATCLOSED, 0.9), (0.0, E.HIHATPEDAL), (0.0, E.SNARE, 0.5), (0.0, E.CRASH, 0.6))
    c = distribute(_score(*group), KIT)
    assert sorted(n.event.value for n in c.notes) == ["CRASH", "HIHATPEDAL", "SNARE"]
    assert [(i.event, i.reason) for i in c.issues] == [(E.HIHATCLOSED, IssueReason.TOO_MANY_HANDS)]


def test_pedal_substitutes_when_three_non_bass_events_coincide() -> None:
    a = distribute(_score((0.0, E.HIHATCLOSED), (0.0, E.SNARE), (0.0, E.CRASH), (0.0, E.BASS)), KIT)
    by_event = {n.event: n.limb for n in a.notes}
    assert by_event[E.HIHATPEDAL] == LF
    assert E.HIHATCLOSED not in by_event
    assert {by_event[E.SNARE], by_event[E.CRASH]} == {LH, RH}
    assert by_event[E.BASS] == RF
    assert [i.action for i in a.issues] == [IssueAction.SUBSTITUTED_PEDAL]
    # two non-bass events: no substitution
    b = distribute(_score((0.0, E.HIHATCLOSED), (0.0, E.SNARE), (0.0, E.BASS)), KIT)
    assert {n.event for n in b.notes} == {E.HIHATCLOSED, E.SNARE, E.BASS} and not b.issues


def test_at_most_two_hand_events() -> None:
    a = distribute(_score((0.0, E.SNARE, 0.9), (0.0, E.CRASH, 0.8), (0.0, E.FLOORTOM, 0.3), (0.0, E.HIGHTOM, 0.2)), KIT)
    hands = [n for n in a.notes if n.limb in (LH, RH)]
    assert len(hands) == 2 and {n.event for n in hands} == {E.SNARE, E.CRASH}
    dropped = [i for i in a.issues if i.reason == IssueReason.TOO_MANY_HANDS]
    assert {i.event for i in dropped} == {E.FLOORTOM, E.HIGHTOM}


def test_double_pedal_takes_fast_bass_notes() -> None:
    notes = [(0.04 * k, E.BASS) for k in range(6)]  # faster than one foot (minTimeGap 50 ms)
    single = distribute(_score(*notes), KIT)
    assert {n.limb for n in single.notes} == {RF}
    assert any(i.reason == IssueReason.TOO_FAST for i in single.issues)
    double = distribute(_score(*notes), load_kit("double_pedal"))
    assert [n.limb for n in double.notes] == [RF, LF] * 3
    assert not double.issues


@pytest.mark.parametrize("ioi", [0.06, 0.075])
def test_hihatopen_ride_hihatopen_without_crossing(ioi: float) -> None:
    """The paper's case: the simple algorithm alternates into a crossing; the better ones do not."""
    score = _score((0.0, E.HIHATOPEN), (ioi, E.RIDE), (2 * ioi, E.HIHATOPEN))
    simple = _limbs(score, "simple")
    assert simple == [("HIHATOPEN", RH), ("RIDE", LH), ("HIHATOPEN", RH)]  # left hand on the ride: crossed
    for algorithm in ("pairwise", "viterbi"):
        assert _limbs(score, algorithm) == [("HIHATOPEN", LH), ("RIDE", RH), ("HIHATOPEN", LH)], algorithm


def test_default_hands_and_alternation() -> None:
    # slow single strokes stay on the preferred hand
    slow = _score(*[(0.5 * k, E.SNARE) for k in range(4)])
    for algorithm in ("simple", "pairwise", "viterbi"):
        assert {limb for _, limb in _limbs(slow, algorithm)} == {LH}
    # a fast single-stroke run alternates under every algorithm
    fast = _score(*[(0.05 * k, E.SNARE) for k in range(8)])
    for algorithm in ("simple", "pairwise", "viterbi"):
        limbs = [limb for _, limb in _limbs(fast, algorithm)]
        assert all(a != b for a, b in zip(limbs, limbs[1:], strict=False)), algorithm


def test_hihat_and_snare_together_follow_pair_preference() -> None:
    score = _score((0.0, E.HIHATCLOSED), (0.0, E.SNARE))
    for algorithm in ("simple", "pairwise", "viterbi"):
        assert dict(_limbs(score, algorithm)) == {"HIHATCLOSED": RH, "SNARE": LH}


def test_viterbi_avoids_intervals_below_min_gap() -> None:
    # 16ths every 0.06 s on hi-hat and snare: one hand cannot (minTimeGap 0.07 s), two can
    events: list[tuple[float, E]] = [(0.06 * k, E.SNARE if k % 4 == 2 else E.HIHATCLOSED) for k in range(32)]
    a = distribute(_score(*events), KIT, "viterbi")
    assert not [i for i in a.issues if i.reason == IssueReason.TOO_FAST]


def test_sticking_patterns_on_rolls() -> None:
    notes = [HandNote(k, 0.1 * k, E.SNARE) for k in range(8)]
    lead = LH  # the snare's preferred hand leads
    other = RH
    expect = {
        Sticking.SINGLE: [lead, other] * 4,
        Sticking.DOUBLE: [lead, lead, other, other] * 2,
        Sticking.PARADIDDLE: [lead, other, lead, lead, other, lead, other, other],
    }
    for sticking, hands in expect.items():
        for algorithm in ("simple", "pairwise", "viterbi"):
            assert assign_hands(notes, KIT, algorithm, sticking) == hands, (sticking, algorithm)


def test_forced_hands_are_respected() -> None:
    notes = [HandNote(0, 0.0, E.RIDE, forced=LH), HandNote(1, 0.5, E.SNARE, forced=RH)]
    for algorithm in ("simple", "pairwise", "viterbi"):
        assert assign_hands(notes, KIT, algorithm) == [LH, RH]


def test_left_handed_kit_mirrors_assignment() -> None:
    score = _score((0.0, E.HIHATCLOSED), (0.0, E.SNARE), (0.0, E.BASS))
    a = distribute(score, load_kit("left_handed"))
    assert {n.event: n.limb for n in a.notes} == {E.HIHATCLOSED: LH, E.SNARE: RH, E.BASS: LF}


def test_pair_table_from_geometry_changes_pairwise() -> None:
    """The kit's pair table covers every stick pair (conventions + geometry): pair-wise sends the hi-hat to the left
    hand when the floor tom follows 0.1 s later; simple keeps both on the right hand (a 0.9 m move in 0.1 s)."""
    assert KIT.pair(E.FLOORTOM, E.HIHATCLOSED) == 1.0  # floor tom right of the hi-hat
    assert KIT.pair(E.HIHATCLOSED, E.SNARE) == 1.0  # the crossed hi-hat convention is kept
    assert KIT.pair(E.SNARE, E.RIM) == 0.0  # same object: no preference
    score = _score((0.0, E.HIHATCLOSED), (0.1, E.FLOORTOM))
    assert _limbs(score, "simple") == [("HIHATCLOSED", RH), ("FLOORTOM", RH)]
    assert _limbs(score, "pairwise") == [("HIHATCLOSED", LH), ("FLOORTOM", RH)]
    left = load_kit("left_handed")
    assert left.pair_preference == KIT.mirrored().pair_preference
