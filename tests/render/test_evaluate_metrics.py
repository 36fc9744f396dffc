"""Matching and metrics of ``batteur evaluate`` on synthetic impact lists (no physics)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from batteur.calibration import Calibration, fit_calibration
from batteur.evaluate import (
    Flag,
    Hit,
    NoteRef,
    aggregate,
    evaluate_performance,
    expected_instrument,
    match,
    plot_result,
)
from common.kit import EventType, load_kit


def notes_at(times: list[float], instrument: str = "snare", velocity: float = 0.5) -> list[NoteRef]:
    return [NoteRef(i, t, instrument, velocity, "SNARE") for i, t in enumerate(times)]


def hits_at(times: list[float], instrument: str = "snare", velocity: float = 3.0) -> list[Hit]:
    return [Hit(t, instrument, velocity, "left_stick_tip") for t in times]


def test_perfect_performance_scores_one() -> None:
    times = [0.0, 0.25, 0.5, 0.75]
    r = evaluate_performance("p", notes_at(times), hits_at(times))
    assert r.f_measure == {"10ms": 1.0, "25ms": 1.0}
    assert r.timing_ms["median_abs"] == 0.0 and r.spurious == 0 and r.missed == []


def test_windows_separate_10_and_25_ms() -> None:
    notes = notes_at([0.0, 1.0, 2.0, 3.0])
    hits = hits_at([0.005, 1.015, 2.030, 3.0])  # within 10, within 25, outside both, exact
    r = evaluate_performance("w", notes, hits)
    assert r.matched == {"10ms": 2, "25ms": 3}
    assert r.precision["25ms"] == pytest.approx(0.75) and r.recall["25ms"] == pytest.approx(0.75)
    assert r.f_measure["10ms"] == pytest.approx(0.5)
    assert r.spurious == 1
    assert [f.reason for f in r.missed] == ["timing"]  # the +30 ms impact is named
    assert "+30.0 ms" in r.missed[0].detail
    # timing over the 25 ms pairs: errors 5, 15, 0 ms
    assert r.timing_ms["median_abs"] == pytest.approx(5.0)
    assert r.timing_ms["median_signed"] == pytest.approx(5.0)
    assert r.timing_loose_ms["n"] == 4


def test_instrument_must_match() -> None:
    notes = notes_at([0.0, 0.5])
    hits = [Hit(0.0, "snare", 3.0), Hit(0.5, "hihat", 3.0, "right_stick_tip")]
    r = evaluate_performance("i", notes, hits)
    assert r.matched["25ms"] == 1 and r.spurious == 1
    assert r.missed[0].reason == "wrong_instrument" and "hihat" in r.missed[0].detail


def test_matching_is_one_to_one_and_optimal() -> None:
    # greedy nearest-first would pair the note at 0.020 with the hit at 0.012 and lose one pair
    notes = notes_at([0.0, 0.020])
    hits = hits_at([0.012, 0.040])
    pairs = match(notes, hits, 0.025)
    assert pairs == [(0, 0), (1, 1)]
    # two hits for one note: one is spurious; one note with two hits never counts twice
    r = evaluate_performance("d", notes_at([0.0]), hits_at([0.001, 0.002]))
    assert r.matched["25ms"] == 1 and r.spurious == 1 and r.precision["25ms"] == 0.5


def test_matching_agrees_with_mir_eval_on_random_lists() -> None:
    mir_eval = pytest.importorskip("mir_eval")
    rng = np.random.default_rng(7)
    for _ in range(20):
        ref = np.sort(rng.uniform(0, 5, 60))
        est = np.sort(np.concatenate([ref + rng.normal(0, 0.015, ref.size), rng.uniform(0, 5, 10)]))
        ours = match(notes_at(list(ref)), hits_at(list(est)), 0.025)
        theirs = mir_eval.util.match_events(ref, est, 0.025)
        assert len(ours) == len(theirs)
        assert all(abs(ref[i] - est[j]) <= 0.025 + 1e-9 for i, j in ours)


def test_missed_notes_always_have_a_reason() -> None:
    notes = notes_at([0.0, 1.0, 2.0, 3.0])
    hits = hits_at([0.0, 2.07])
    flags = [Flag(1, 1.0, "SNARE", "too_fast", "planner", "dropped: under minTimeGap")]
    r = evaluate_performance("m", notes, hits, flags)
    reasons = {f.index: f.reason for f in r.missed}
    assert reasons == {1: "too_fast", 2: "timing", 3: "no_contact"}
    assert r.missed_by_reason == {"no_contact": 1, "timing": 1, "too_fast": 1}
    assert len(r.missed) == r.notes - r.matched["25ms"]


def test_spearman_follows_velocity_rank() -> None:
    times = [0.0, 0.5, 1.0, 1.5, 2.0]
    vel = [0.1, 0.3, 0.5, 0.7, 0.9]
    notes = [NoteRef(i, t, "snare", v, "SNARE") for i, (t, v) in enumerate(zip(times, vel, strict=True))]
    rising = [Hit(t, "snare", v) for t, v in zip(times, [1.0, 2.0, 3.0, 4.0, 5.0], strict=True)]
    falling = [Hit(t, "snare", v) for t, v in zip(times, [5.0, 4.0, 3.0, 2.0, 1.0], strict=True)]
    assert evaluate_performance("up", notes, rising).spearman == pytest.approx(1.0)
    assert evaluate_performance("down", notes, falling).spearman == pytest.approx(-1.0)
    assert evaluate_performance("few", notes[:2], rising[:2]).spearman is None


def test_within_sound_spearman_ignores_the_sounds_different_gains() -> None:
    """Each sound ranked right but a soft pedal chick beside stick strokes: pooled rank breaks, within holds."""
    vel = [0.2, 0.4, 0.6, 0.8, 1.0]
    notes = [NoteRef(i, float(i), "hihat", v, "HIHATCLOSED") for i, v in enumerate(vel)]
    notes += [NoteRef(5 + i, 5.0 + i, "hihat", v, "HIHATPEDAL") for i, v in enumerate(vel)]
    hits = [Hit(float(i), "hihat", 1.0 + 2 * v) for i, v in enumerate(vel)]
    hits += [Hit(5.0 + i, "hihat", 0.1 + 0.3 * v) for i, v in enumerate(vel)]
    r = evaluate_performance("hh", notes, hits)
    assert r.spearman is not None and r.spearman < 0.7
    assert r.spearman_within_sound == pytest.approx(1.0)
    # one sound played backwards: the within-sound figure falls to the weighted mean (1 - 1) / 2
    backwards = hits[:5] + [Hit(5.0 + i, "hihat", 0.4 - 0.3 * v) for i, v in enumerate(vel)]
    assert evaluate_performance("hh", notes, backwards).spearman_within_sound == pytest.approx(0.0)
    agg = aggregate([r, r])
    assert agg["spearman_within_sound"] == pytest.approx(1.0)
    assert set(agg["spearman_by_sound"]) == {"hihat/HIHATCLOSED", "hihat/HIHATPEDAL"}
    # a sound with fewer than five pairs does not count
    assert evaluate_performance("few", notes[:4], hits[:4]).spearman_within_sound is None


def test_aggregate_is_micro_averaged() -> None:
    a = evaluate_performance("a", notes_at([0.0, 1.0]), hits_at([0.0, 1.0]))
    b = evaluate_performance("b", notes_at([0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]), hits_at([0.0]))
    agg = aggregate([a, b])
    assert agg["notes"] == 10 and agg["impacts"] == 3
    assert agg["recall"]["25ms"] == pytest.approx(0.3)
    assert agg["precision"]["25ms"] == pytest.approx(1.0)
    assert agg["missed"] == 7
    json.dumps(agg)


def test_pedal_events_sound_on_the_instrument_the_pedal_drives() -> None:
    kit = load_kit()
    assert expected_instrument(kit, EventType.HIHATPEDAL) == expected_instrument(kit, EventType.HIHATCLOSED)
    assert expected_instrument(kit, EventType.BASS) == kit.object_for(EventType.BASS).id
    assert expected_instrument(kit, EventType.SNARE) == "snare"


def test_plots_are_written(tmp_path: Path) -> None:
    r = evaluate_performance("plot.mid", notes_at([0.0, 0.5, 1.0]), hits_at([0.004, 0.49, 1.3]))
    paths = plot_result(r, tmp_path)
    assert [p.name for p in paths] == ["plot_pianoroll.png", "plot_timing.png"]
    assert all(p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for p in paths)


def test_calibration_fits_lag_and_velocity_and_shifts_notes(tmp_path: Path) -> None:
    times = [0.2 * k for k in range(20)]
    vel = [0.2 + 0.03 * k for k in range(20)]
    notes = [NoteRef(i, t, "snare", v, "SNARE") for i, (t, v) in enumerate(zip(times, vel, strict=True))]
    late = [Hit(t + 0.012, "snare", 1.0 + 4.0 * v) for t, v in zip(times, vel, strict=True)]
    r = evaluate_performance("c", notes, late)
    cal = fit_calibration([r], load_kit())
    assert cal.timing["snare"] == pytest.approx(0.012, abs=1e-6)
    assert cal.velocity["snare"] == pytest.approx((1.0, 4.0), abs=1e-6)
    cal.save(tmp_path / "cal.json")
    again = Calibration.load(tmp_path / "cal.json")
    assert again.lag("snare") == pytest.approx(0.012)
    # a render made with it that is still 2 ms late adds up
    r2 = evaluate_performance("c2", notes, [Hit(t + 0.002, "snare", 3.0) for t in times])
    assert fit_calibration([r2], load_kit(), base=again).timing["snare"] == pytest.approx(0.014, abs=1e-6)
    with pytest.raises(ValueError, match="not a calibration"):
        (tmp_path / "bad.json").write_text("[1, 2")
        Calibration.load(tmp_path / "bad.json")
    for text, says in (('{"timing": {"snare": 0.01}}', "unknown keys ['timing']"),  # misspelt: would do nothing
                       ('{"timing_s": {"snare": NaN}}', "not a finite number")):
        (tmp_path / "bad.json").write_text(text)
        with pytest.raises(ValueError, match=re.escape(says)):
            Calibration.load(tmp_path / "bad.json")


def test_calibration_separates_events_on_one_object_and_moves_assignment_notes() -> None:
    import dataclasses

    from common.kit import Limb
    from common.score.limbs import Assignment, Note

    kit = load_kit()
    hh = expected_instrument(kit, EventType.HIHATCLOSED)
    times = [0.5 * k for k in range(12)]
    notes = [NoteRef(2 * k, t, hh, 0.5, "HIHATCLOSED") for k, t in enumerate(times)]
    notes += [NoteRef(2 * k + 1, t + 0.25, hh, 0.5, "HIHATPEDAL") for k, t in enumerate(times)]
    hits = [Hit(t - 0.003, hh, 3.0) for t in times] + [Hit(t + 0.25 - 0.055, hh, 1.0) for t in times]
    cal = fit_calibration([evaluate_performance("h", notes, hits)], kit)
    assert cal.lag(hh, "HIHATCLOSED") == pytest.approx(-0.003, abs=1e-6)
    assert cal.lag(hh, "HIHATPEDAL") == pytest.approx(-0.05)  # -55 ms measured (beyond 25 ms), capped at 50 ms
    assignment = Assignment([Note(0, 1.0, EventType.HIHATPEDAL, 0.5, Limb.LEFT_FOOT),
                             Note(1, 1.0, EventType.HIHATCLOSED, 0.5, Limb.RIGHT_HAND)])
    moved = cal.apply(assignment, kit)
    by_event = {n.event: n.time for n in moved.notes}
    assert by_event[EventType.HIHATPEDAL] == pytest.approx(1.05)  # early lag: planned later
    assert by_event[EventType.HIHATCLOSED] == pytest.approx(1.003)
    assert [n.time for n in assignment.notes] == [1.0, 1.0]  # the original is untouched
    assert dataclasses.is_dataclass(moved)
