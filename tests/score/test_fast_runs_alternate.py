"""Notes one hand would play faster than a drummer keeps up single-handed go to a free other hand, hand to hand
(common/score/hands.py ``RUN_INTERVAL_S``, ``Costs.run``): a 32nd-note roll and 16th-note triplets at 100 bpm and a
drag's three notes alternate; time kept on the hi-hat against a backbeat stays with one hand. Before, the shortest-path
search (the default) gave all 32 strokes of a roll 75 ms apart to the left hand while the right did nothing (the speed
cost, at most 0.3, never outweighed leaving the preferred hand, 1). ``simple`` and ``pairwise`` stay the paper's
baselines (alternation below minTimeGap only)."""

from __future__ import annotations

import pytest

from common.kit import EventType as E
from common.kit import Limb, load_kit
from common.score.events import DrumEvent, Score
from common.score.limbs import distribute

KIT = load_kit()
LH, RH = Limb.LEFT_HAND, Limb.RIGHT_HAND


def _hands(events: list[tuple[float, E, float]]) -> list[tuple[float, E, Limb]]:
    """(time, event, limb) of each stick note of ``events`` (time s, event, velocity) as distributed."""
    score = Score([DrumEvent(t, e, v) for t, e, v in events])
    return [(n.time, n.event, n.limb) for n in distribute(score, KIT).notes if n.limb in (LH, RH)]


def _alternates(limbs: list[Limb]) -> bool:
    return all(a != b for a, b in zip(limbs, limbs[1:], strict=False))


@pytest.mark.parametrize("interval_s", [0.075, 0.1])  # 32nd notes, 16th-note triplets at 100 bpm
def test_a_fast_snare_run_is_played_hand_to_hand(interval_s: float) -> None:
    """A crescendo roll with a kick under it: every stroke on the other hand than the one before, both hands used."""
    roll = [(0.5 + k * interval_s, E.SNARE, 0.47 + 0.015 * k) for k in range(32)]
    kicks = [(0.5 + 0.6 * k, E.BASS, 0.8) for k in range(4)]
    limbs = [limb for _, _, limb in _hands(sorted(roll + kicks, key=lambda e: e[0]))]
    assert len(limbs) == 32
    assert _alternates(limbs), "".join("L" if h == LH else "R" for h in limbs)


def test_a_drag_with_both_hands_free_alternates() -> None:
    """Two soft 32nd-note graces (75 ms apart at 100 bpm) and the accent: no hand plays two of them in a row (all
    three were the left hand's)."""
    drag = [(1.0, E.SNARE, 0.35), (1.075, E.SNARE, 0.35), (1.15, E.SNARE, 0.9)]
    limbs = [limb for _, _, limb in _hands(drag + [(1.15, E.BASS, 0.8)])]
    assert _alternates(limbs), limbs


def test_hands_still_take_turns_only_when_notes_come_that_fast() -> None:
    """Slower than the fastest one-hand run (quintuplets at 100 bpm, 120 ms): the snare's hand plays them all."""
    run = [(0.5 + k * 0.12, E.SNARE, 0.6) for k in range(20)]
    assert {limb for _, _, limb in _hands(run)} == {LH}


@pytest.mark.parametrize("bpm", [100, 140, 160])
def test_a_groove_keeps_time_with_one_hand_and_the_backbeat_with_the_other(bpm: float) -> None:
    """16th notes on the closed hi-hat (150-94 ms apart: a run on a cymbal is time kept, however fast) with the
    snare on 2 and 4: the right hand plays every hi-hat note, the left every snare note."""
    beat = 60.0 / bpm
    hats = [(k * beat / 4, E.HIHATCLOSED, 0.6 if k % 2 else 0.8) for k in range(32)]
    snares = [(b * beat, E.SNARE, 0.9) for b in (1, 3, 5, 7)]
    kicks = [(b * beat, E.BASS, 0.8) for b in (0, 2, 4, 6)]
    notes = _hands(sorted(hats + snares + kicks, key=lambda e: e[0]))
    assert {limb for _, event, limb in notes if event == E.HIHATCLOSED} == {RH}
    assert {limb for _, event, limb in notes if event == E.SNARE} == {LH}


def test_a_drag_under_the_hi_hat_leaves_the_hat_hand_keeping_time() -> None:
    """8th notes on the hi-hat (300 ms) and a drag into each backbeat: the right hand stays on the hi-hat (a dash to
    the snare for a grace and back in 75 ms made its stick strike beside the other's), the left plays the drag."""
    beat = 0.6
    hats = [(k * beat / 2, E.HIHATCLOSED, 0.63) for k in range(16)]
    drags = [(b * beat + d, E.SNARE, v) for b in (1, 3, 5, 7) for d, v in ((-0.15, 0.35), (-0.075, 0.35), (0, 0.9))]
    notes = _hands(sorted(hats + drags, key=lambda e: e[0]))
    assert {limb for _, event, limb in notes if event == E.HIHATCLOSED} == {RH}
    assert {limb for _, event, limb in notes if event == E.SNARE} == {LH}
