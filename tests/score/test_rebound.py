"""Rebound doubles (diddles): drags, ruffs and double-stroke rolls; notes no hand can play are reported."""

from __future__ import annotations

from itertools import groupby

import pytest

from common.gesture.plan import IssueAction, IssueReason
from common.kit import EventType as E
from common.kit import Limb, load_kit
from common.score.events import DrumEvent, Score
from common.score.hands import HandNote, assign_hands
from common.score.limbs import HANDS, Assignment, distribute
from common.score.rebound import Interval, Stroke, classify, rebound_gap

KIT = load_kit()
LH, RH = Limb.LEFT_HAND, Limb.RIGHT_HAND


def _score(*events: tuple[float, E, float]) -> Score:
    return Score(sorted((DrumEvent(t, e, v) for t, e, v in events), key=lambda d: d.time))


def _hand_intervals(a: Assignment) -> list[Interval]:
    """Every stick note's interval kind, recomputed from the notes (independent of Note.rebound)."""
    kinds = []
    for hand in HANDS:
        prev, prev_rebound = None, False
        for n in a.of(hand):
            cur = Stroke(n.time, n.event, n.pitch, n.velocity)
            kind = classify(KIT, prev, prev_rebound, cur)
            assert n.rebound == (kind == Interval.REBOUND), n
            kinds.append(kind)
            prev, prev_rebound = cur, kind == Interval.REBOUND
    return kinds


def test_classify_rebound_double_rules() -> None:
    stroke = Stroke(0.0, E.SNARE, None, 0.5)
    assert classify(KIT, None, False, stroke) == Interval.FIRST
    assert classify(KIT, stroke, False, Stroke(0.08, E.SNARE, None, 0.5)) == Interval.FULL
    assert classify(KIT, stroke, False, Stroke(0.035, E.SNARE, None, 0.45)) == Interval.REBOUND
    assert classify(KIT, stroke, False, Stroke(0.035, E.SNARE, None, 0.55)) == Interval.REBOUND  # within the margin
    assert classify(KIT, stroke, False, Stroke(0.035, E.SNARE, None, 0.9)) == Interval.TOO_FAST  # louder: not a bounce
    assert classify(KIT, stroke, True, Stroke(0.035, E.SNARE, None, 0.45)) == Interval.TOO_FAST  # third bounce
    assert classify(KIT, stroke, False, Stroke(0.025, E.SNARE, None, 0.45)) == Interval.TOO_FAST  # below 30 ms
    assert classify(KIT, stroke, False, Stroke(0.035, E.RIM, None, 0.45)) == Interval.TOO_FAST  # another spot
    assert classify(KIT, stroke, False, Stroke(0.035, E.HIGHTOM, None, 0.45)) == Interval.TOO_FAST  # another drum
    # the rebound minimum is the kit's up to mf and rises to the full minTimeGap at velocity 1
    assert rebound_gap(KIT, E.SNARE, 0.5) == pytest.approx(KIT.rebound_min_time_gap)
    assert rebound_gap(KIT, E.SNARE, 1.0) == pytest.approx(KIT.spec(E.SNARE).min_time_gap)
    assert KIT.rebound_min_time_gap < rebound_gap(KIT, E.SNARE, 0.8) < KIT.spec(E.SNARE).min_time_gap
    loud = Stroke(0.0, E.SNARE, None, 1.0)
    assert classify(KIT, loud, False, Stroke(0.04, E.SNARE, None, 1.0)) == Interval.TOO_FAST
    # feet never bounce doubles
    kick = Stroke(0.0, E.BASS, None, 0.5)
    assert classify(KIT, kick, False, Stroke(0.04, E.BASS, None, 0.5)) == Interval.TOO_FAST


def test_kit_rebound_fields_have_defaults_and_survive_mirroring() -> None:
    kit = KIT.model_copy(update={"rebound_min_time_gap": 0.04})
    assert kit.mirrored().rebound_min_time_gap == 0.04
    assert load_kit("left_handed").rebound_min_time_gap == KIT.rebound_min_time_gap == 0.03
    spec = KIT.spec(E.SNARE).model_copy(update={"rebound_min_time_gap": 0.045})
    per_event = KIT.model_copy(update={"events": {**KIT.events, E.SNARE: spec}})
    assert rebound_gap(per_event, E.SNARE, 0.3) == pytest.approx(0.045)


def test_drag_grace_notes_are_a_rebound_double() -> None:
    """Drag: two soft grace notes 35 ms apart, then the accent; the right hand is busy on the ride just before."""
    score = _score((0.0, E.RIDE, 0.6), (0.40, E.RIDE, 0.6), (0.42, E.SNARE, 0.3), (0.455, E.SNARE, 0.25),
                   (0.50, E.SNARE, 0.9), (0.80, E.RIDE, 0.6))
    for algorithm in ("viterbi",):
        a = distribute(score, KIT, algorithm)
        snares = [n for n in a.notes if n.event == E.SNARE]
        assert [(n.limb, n.rebound) for n in snares] == [(LH, False), (LH, True), (RH, False)]
        assert not a.issues
        assert Interval.TOO_FAST not in _hand_intervals(a)


def test_ruff_three_grace_notes_no_drop() -> None:
    """Three-stroke ruff (grace notes 30 ms apart) into an accent: alternation with one bounce, nothing left out."""
    score = _score((0.40, E.SNARE, 0.3), (0.43, E.SNARE, 0.3), (0.46, E.SNARE, 0.25), (0.52, E.SNARE, 0.9))
    a = distribute(score, KIT, "viterbi")
    assert len(a.notes) == 4 and not a.issues
    kinds = _hand_intervals(a)
    assert Interval.TOO_FAST not in kinds and kinds.count(Interval.REBOUND) == 1
    # five-stroke roll, every 30 ms into the accent: two doubles and the accent (RRLLR or LLRRL), nothing left out
    roll = _score(*[(0.40 + 0.03 * k, E.SNARE, 0.3) for k in range(4)], (0.52, E.SNARE, 0.9))
    b = distribute(roll, KIT, "viterbi")
    assert len(b.notes) == 5 and not b.issues
    hands = [n.limb for n in b.notes]
    assert hands[0] == hands[1] != hands[2] == hands[3] != hands[4]
    assert [n.rebound for n in b.notes] == [False, True, False, True, False]


def test_double_stroke_roll_faster_than_singles_is_rrll() -> None:
    """Snare every 30 ms: single strokes would need 60 ms full strokes; doubles (one bounce each) fit."""
    notes = [HandNote(k, 0.03 * k, E.SNARE, velocity=0.4) for k in range(12)]
    hands = assign_hands(notes, KIT, "viterbi")
    assert None not in hands
    # doubles (a single may start or end the roll): no hand plays three in a row, none plays singles
    runs = [len(list(g)) for _, g in groupby(hands)]
    assert max(runs) == 2 and runs.count(2) >= 5
    a = distribute(Score([DrumEvent(n.time, n.event, 0.4) for n in notes]), KIT, "viterbi")
    assert not a.issues and sum(n.rebound for n in a.notes) == runs.count(2)
    assert Interval.TOO_FAST not in _hand_intervals(a)


def test_three_notes_inside_the_rebound_minimum_are_flagged() -> None:
    """Three notes within 24 ms on different drums: two hands, no bounce possible; one is dropped and said so."""
    score = _score((0.5, E.SNARE, 0.8), (0.512, E.HIGHTOM, 0.4), (0.524, E.FLOORTOM, 0.7))
    a = distribute(score, KIT, "viterbi")
    assert len(a.notes) == 2 and Interval.TOO_FAST not in _hand_intervals(a)
    (issue,) = a.issues
    assert issue.reason == IssueReason.TOO_FAST and issue.action == IssueAction.DROPPED
    assert issue.event == E.HIGHTOM  # the quietest goes
    assert "no hand can play it" in issue.detail and "rebound minimum 30 ms" in issue.detail
    # on one drum the left-out note is merged into the nearest stroke (they sound as one)
    same = _score((0.5, E.SNARE, 0.5), (0.512, E.SNARE, 0.4), (0.524, E.SNARE, 0.9))
    b = distribute(same, KIT, "viterbi")
    assert len(b.notes) == 2 and [i.action for i in b.issues] == [IssueAction.MERGED]
    left_out = b.issues[0]
    assert left_out.time == pytest.approx(0.512)  # the quietest goes
    assert any(f"so it sounds as one stroke with the {h} hand's SNARE at {t} s" in left_out.detail
               for t in ("0.500", "0.524") for h in ("left", "right"))


def test_a_note_no_hand_can_play_says_each_hands_strokes_as_a_drummer_reads_them() -> None:
    """A flam's grace 20 ms before the main stroke, the left hand's previous stroke 1.18 s earlier: the detail read
    ``left_hand 1180 ms after and 20 ms before its strokes`` (backwards: the note comes after the earlier stroke) and
    evaluate said "merged" twice (``too_fast (merged: ... merged into the SNARE``)."""
    score = _score((0.6, E.SNARE, 0.9), (1.78, E.SNARE, 0.4), (1.8, E.SNARE, 0.9), (1.8, E.HIHATCLOSED, 0.6),
                   (1.5, E.HIHATCLOSED, 0.6), (2.1, E.HIHATCLOSED, 0.6))
    a = distribute(score, KIT, "viterbi")
    (issue,) = a.issues
    assert issue.action == IssueAction.MERGED and issue.time == pytest.approx(1.78)
    assert issue.detail == ("no hand can play it in time (left hand: its previous stroke 1180 ms before, its next 20 "
                            "ms after; right hand: its previous stroke 280 ms before, its next 20 ms after; minTimeGap "
                            "70 ms, rebound minimum 30 ms), so it sounds as one stroke with the left hand's SNARE at "
                            "1.800 s")
    assert issue.detail.count("merged") == 0  # the action says it once, wherever it is printed


def test_simple_and_pairwise_flag_too_fast_but_accept_bounces() -> None:
    score = _score((0.0, E.SNARE, 0.5), (0.035, E.SNARE, 0.45), (0.07, E.SNARE, 0.9))
    a = distribute(score, KIT, "simple")
    assert [n.rebound for n in a.notes if n.limb in HANDS].count(True) <= 1
    kinds = _hand_intervals(a)
    too_fast = [i for i in a.issues if i.reason == IssueReason.TOO_FAST]
    assert len(too_fast) == kinds.count(Interval.TOO_FAST)
    assert all(i.action == IssueAction.PLAYED_ANYWAY for i in too_fast)
