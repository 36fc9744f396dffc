"""A note beyond its hand's reach: the other hand plays it when it reaches it and is free then; otherwise the note
is flagged ``unreachable`` and dropped, and its hand does not travel to it (its reachable notes play as if the far
one were not in the score). ``check_feasibility`` run again adds nothing."""

from __future__ import annotations

import numpy as np

from common.gesture.plan import FeasibilityIssue, IssueAction, IssueReason
from common.gesture.planner import plan_gestures
from common.kit import EventType, Kit, Limb, load_kit
from common.score.events import DrumEvent, Score
from common.score.limbs import SHOULDERS, Assignment, check_feasibility, distribute, hand_reach, shoulders
from common.score.text import parse_text
from tests.far_kits import china_at

E = EventType
SNARES_AND_CHINA = "tempo 120\nmeter 4/4\nSN |x.x.x.x.|\nCH |....x...|\n"
"""A bar of four snare notes and a china note with the third (the left hand plays the snare, the right the china)."""
EDGE_KIT = china_at(load_kit("default"), 1.10)
"""The china in the default drummer's reach (1.15 m), beyond a 1.40 m drummer's (1.02 m)."""


def _unreachable(issues: list[FeasibilityIssue]) -> list[tuple[int, IssueAction]]:
    return [(i.note_index, i.action) for i in issues if i.reason == IssueReason.UNREACHABLE]


def _farthest_knot(kit: Kit, height_m: float, assignment: Assignment, score: Score, limb: Limb) -> float:
    """Metres from ``limb``'s shoulder to its farthest planned knot."""
    knots = plan_gestures(assignment, kit, score).trajectories[limb].positions
    return float(np.linalg.norm(knots - np.array(shoulders(kit, height_m)[limb]), axis=1).max())


def test_a_note_no_free_hand_reaches_is_flagged_and_its_hand_does_not_go_there() -> None:
    score = parse_text(SNARES_AND_CHINA)
    small = distribute(score, EDGE_KIT, height_m=1.4)
    assert _unreachable(small.issues) == [(2, IssueAction.DROPPED)]  # was: played anyway, and every note missed
    assert [(n.time, n.event) for n in small.notes] == [(0.0, E.SNARE), (0.5, E.SNARE), (1.0, E.SNARE),
                                                        (1.5, E.SNARE)]
    plan = plan_gestures(small, EDGE_KIT, score)
    assert [(s.time, s.event) for s in plan.strokes] == [(n.time, n.event) for n in small.notes]  # no china stroke
    assert _farthest_knot(EDGE_KIT, 1.4, small, score, Limb.RIGHT_HAND) <= hand_reach(1.4)  # was 1.21 m
    # the default drummer reaches it: played as before
    tall = distribute(score, EDGE_KIT)
    assert _unreachable(tall.issues) == [] and (1.0, E.CHINA, Limb.RIGHT_HAND) in [
        (n.time, n.event, n.limb) for n in tall.notes]


def test_the_hand_plays_its_reachable_notes_as_if_the_far_one_were_not_written() -> None:
    """Hi-hat eighths on the right hand, a china in place of the fifth: the right hand's trajectory is the one of
    the same bar without the china."""
    with_china = parse_text("tempo 120\nmeter 4/4\nHH |xxxx.xxx|\nSN |..x...x.|\nCH |....x...|\n")
    without = parse_text("tempo 120\nmeter 4/4\nHH |xxxx.xxx|\nSN |..x...x.|\n")
    small = distribute(with_china, EDGE_KIT, height_m=1.4)
    assert [i.event for i in small.issues if i.reason == IssueReason.UNREACHABLE] == [E.CHINA]
    plain = distribute(without, EDGE_KIT, height_m=1.4)
    assert [(n.time, n.event, n.limb) for n in small.notes] == [(n.time, n.event, n.limb) for n in plain.notes]
    ours = plan_gestures(small, EDGE_KIT, with_china).trajectories[Limb.RIGHT_HAND]
    theirs = plan_gestures(plain, EDGE_KIT, without).trajectories[Limb.RIGHT_HAND]
    assert np.array_equal(ours.times, theirs.times) and np.array_equal(ours.positions, theirs.positions)


def _china_left(kit: Kit) -> Kit:
    """``kit`` with its china out to the left: 0.95 m from the default drummer's left shoulder (in its reach),
    1.32 m from the right one (beyond)."""
    direction = np.array([-0.95, 0.3, 0.0]) / np.linalg.norm([-0.95, 0.3, 0.0])
    wanted = np.array(SHOULDERS[Limb.LEFT_HAND]) + 0.95 * direction
    delta = wanted - np.array(kit.hit_point(E.CHINA)[0])
    objects = [o.model_copy(update={"position": tuple(float(p + d) for p, d in zip(o.position, delta, strict=True))})
               if o.id == "china" else o for o in kit.objects]
    return kit.model_copy(update={"objects": objects})


def test_a_note_beyond_its_hand_goes_to_the_other_hand_when_that_one_reaches_it_and_is_free() -> None:
    kit = _china_left(load_kit("default"))
    right = np.array(SHOULDERS[Limb.RIGHT_HAND])
    assert np.linalg.norm(np.array(kit.hit_point(E.CHINA)[0]) - right) > hand_reach()
    # the china is the right hand's (preferred); the left hand is free at 1.0 s
    free = Score([DrumEvent(0.0, E.SNARE, 0.7), DrumEvent(1.0, E.CHINA, 0.7, limb=Limb.RIGHT_HAND),
                  DrumEvent(2.0, E.SNARE, 0.7)])
    moved = distribute(free, kit)
    assert [(n.event, n.limb) for n in moved.notes if n.event == E.CHINA] == [(E.CHINA, Limb.LEFT_HAND)]
    assert _unreachable(moved.issues) == [(1, IssueAction.MOVED_TO_OTHER_HAND)]
    assert _farthest_knot(kit, 1.75, moved, free, Limb.RIGHT_HAND) <= hand_reach()
    # the left hand plays a snare note at the same time: it is not free, the china is dropped
    busy = Score([DrumEvent(1.0, E.SNARE, 0.7, limb=Limb.LEFT_HAND), DrumEvent(1.0, E.CHINA, 0.7)])
    dropped = distribute(busy, kit)
    assert _unreachable(dropped.issues) == [(1, IssueAction.DROPPED)]
    assert [(n.event, n.limb) for n in dropped.notes] == [(E.SNARE, Limb.LEFT_HAND)]
    # ... or one too soon before it (40 ms: under the snare's and the china's minTimeGap, no rebound across objects)
    soon = Score([DrumEvent(0.96, E.SNARE, 0.7, limb=Limb.LEFT_HAND), DrumEvent(1.0, E.CHINA, 0.7),
                  DrumEvent(2.0, E.SNARE, 0.7, limb=Limb.LEFT_HAND)])
    assert _unreachable(distribute(soon, kit).issues) == [(1, IssueAction.DROPPED)]
    # ... or one too soon after it (the china's minTimeGap is 150 ms)
    after = Score([DrumEvent(1.0, E.CHINA, 0.7), DrumEvent(1.05, E.SNARE, 0.7, limb=Limb.LEFT_HAND)])
    assert _unreachable(distribute(after, kit).issues) == [(0, IssueAction.DROPPED)]


def test_check_feasibility_run_again_adds_nothing() -> None:
    """Too fast (played anyway and dropped), crossed and unreachable notes, checked a second and a third time."""
    score = Score([DrumEvent(0.0, E.SNARE, 0.7), DrumEvent(0.04, E.SNARE, 0.9), DrumEvent(0.06, E.SNARE, 0.9),
                   DrumEvent(0.5, E.RIDE, 0.7, limb=Limb.LEFT_HAND), DrumEvent(0.5, E.HIHATCLOSED, 0.7),
                   DrumEvent(1.0, E.CHINA, 0.7), DrumEvent(1.5, E.SNARE, 0.7)])
    for algorithm in ("simple", "viterbi"):
        assignment = distribute(score, EDGE_KIT, algorithm, height_m=1.4)
        reasons = {i.reason for i in assignment.issues}
        if algorithm == "simple":
            assert {IssueReason.TOO_FAST, IssueReason.CROSSING, IssueReason.UNREACHABLE} <= reasons
        issues, notes = list(assignment.issues), list(assignment.notes)
        for _ in range(2):
            check_feasibility(assignment, EDGE_KIT, height_m=1.4)
            assert assignment.issues == issues and assignment.notes == notes, algorithm


def test_the_hand_assignment_gives_a_note_to_the_hand_that_reaches_it() -> None:
    """The double-pedal kit's second ride (pitch 59, out to the left) is 1.03 m from a 1.40 m drummer's right
    shoulder (reach 1.02 m): the left hand plays it, the right takes the snare beside it, and nothing is lost."""
    kit = load_kit("double_pedal")
    events = [DrumEvent(k * 0.25, E.RIDE, 0.7, pitch=59) for k in range(8)]
    events += [DrumEvent(t, E.SNARE, 0.7) for t in (0.5, 1.5)]
    score = Score(sorted(events, key=lambda e: e.time))
    small = distribute(score, kit, height_m=1.4)
    assert {n.limb for n in small.notes if n.event == E.RIDE} == {Limb.LEFT_HAND}
    assert {n.limb for n in small.notes if n.event == E.SNARE} == {Limb.RIGHT_HAND}
    assert len(small.notes) == 10 and _unreachable(small.issues) == []  # was: 8 flagged, played anyway
    # the default drummer's right hand reaches it, but beside a snare the left hand takes it: out to the left, it
    # is not the first ride the kit's RIDE,SNARE preference is about (the right hand over the left's snare crossed
    # the arms, and was flagged so)
    default = distribute(score, kit)
    with_snare = {n.time for n in default.notes if n.event == E.SNARE}
    assert {n.limb for n in default.notes if n.event == E.RIDE and n.time in with_snare} == {Limb.LEFT_HAND}
    assert {n.limb for n in default.notes if n.event == E.RIDE and n.time not in with_snare} == {Limb.RIGHT_HAND}
    assert [i for i in default.issues if i.reason == IssueReason.CROSSING] == []
