"""``batteur render --jobs N``: a score rendered in time segments on several processes (batteur/segments.py)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from batteur import evaluate, render
from batteur.segments import Segment, SegmentResult, merge, plan_segments
from common.bus import OfflineRunner
from common.core import Outgoing
from common.gesture.plan import GesturePlan, LimbTrajectory
from common.kit import Limb
from common.messages import OscMessage
from common.messages.events import Impact
from common.messages.interaction import Damping, ImpactEnd

ROCK = """tempo 100
meter 4/4
""" + "\n\n".join(["HH |x.x.x.x.x.x.x.x.|\nSN |....X.......X...|\nBD |x.......x.x.....|"] * 6) + "\n"
"""Six bars of a rock beat (about 14.4 s): both hands and the kick foot."""


def test_segments_cut_at_multiples_and_a_short_tail_joins_the_last() -> None:
    segs = plan_segments(70.0, 30.0, 3.0)
    assert [(s.start_s, s.end_s) for s in segs] == [(0.0, 30.0), (30.0, 70.0)]  # 10 s left: joined
    assert segs[0].run_from_s == 0.0 and segs[1].run_from_s == 27.0  # a lead-in before every later one
    assert segs[0].run_to_s == pytest.approx(30.25) and segs[1].run_to_s == 70.0
    assert [(s.start_s, s.end_s) for s in plan_segments(80.0, 30.0, 3.0)] == [(0.0, 30.0), (30.0, 60.0),
                                                                                 (60.0, 80.0)]
    assert len(plan_segments(5.0, 30.0, 3.0)) == 1
    with pytest.raises(ValueError, match="must be finite and > 0"):
        plan_segments(10.0, 0.0)
    with pytest.raises(ValueError, match="warm-up"):
        plan_segments(10.0, 5.0, 0.2)


def _impact(seq: int, t: float) -> Impact:
    return Impact(seq=seq, time=t, instrument="snare", zone="centre", r=0.2, theta=0.0, velocity=2.0, impulse=0.0,
                  peak_force=0.0, duration=0.0, part="left_stick_tip")


def _end(seq: int, t: float) -> ImpactEnd:
    return ImpactEnd(seq=seq, time=t, instrument="snare", kind="strike", impulse=0.01, peak_force=50.0,
                     duration=0.002, part="left_stick_tip")


def test_merge_orders_by_time_and_numbers_impacts_again() -> None:
    a = SegmentResult(0, [(1.0, "interaction", "sound", _impact(0, 1.0)), (1.004, "interaction", "sound", _end(0, 1.0)),
                          (2.0, "interaction", "sound", _impact(1, 2.0))], 2, {}, 0.0)
    # the second worker numbered from 0 as well; one of its impacts straddles into its window late
    b = SegmentResult(1, [(3.0, "interaction", "sound", _impact(0, 3.0)),
                          (3.5, "interaction", "sound", Damping(seq=0, time=3.5, instrument="snare",
                                                                part="left_stick", state=1, zone="centre", r=0.1,
                                                                theta=0.0, force=2.0)),
                          (3.003, "interaction", "sound", _end(0, 3.0))], 1, {}, 0.0)
    merged = merge([b, a])
    assert [m.time for _, _, _, m in merged] == [1.0, 1.0, 2.0, 3.0, 3.0, 3.5]
    seqs = [(type(m).__name__, m.seq) for _, _, _, m in merged]
    assert seqs == [("Impact", 0), ("ImpactEnd", 0), ("Impact", 1), ("Impact", 2), ("ImpactEnd", 2), ("Damping", 0)]


def test_a_plan_from_a_time_keeps_the_knots_from_then_on() -> None:
    times = np.array([0.0, 0.5, 1.0, 1.5])
    pos = np.arange(12, dtype=float).reshape(4, 3)
    plan = GesturePlan({Limb.LEFT_HAND: LimbTrajectory(Limb.LEFT_HAND, times, pos, np.zeros((4, 3))),
                        Limb.RIGHT_FOOT: LimbTrajectory(Limb.RIGHT_FOOT, times[:2], pos[:2], np.zeros((2, 3)))},
                       [], start_time=0.0, end_time=1.5)
    later = plan.from_time(0.7)
    assert later.trajectories[Limb.LEFT_HAND].times.tolist() == [1.0, 1.5]
    assert later.trajectories[Limb.LEFT_HAND].positions[0].tolist() == [6.0, 7.0, 8.0]
    assert later.trajectories[Limb.RIGHT_FOOT].times.tolist() == [0.5]  # done by then: it stays where it ended
    assert later.start_time == 0.0 and later.end_time == 1.5


class _Clock:
    ROLE = "physics"
    rate_hz = 100.0

    def __init__(self) -> None:
        self.steps: list[float] = []

    def handle(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        return []

    def step(self, now: float) -> list[Outgoing]:
        self.steps.append(now)
        return []


def test_an_offline_run_can_start_later() -> None:
    clock = _Clock()
    OfflineRunner([clock], start_s=2.005).run_until(2.05)
    assert clock.steps == pytest.approx([2.01, 2.02, 2.03, 2.04, 2.05])


def test_negative_jobs_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    score = tmp_path / "rock.txt"
    score.write_text(ROCK)
    assert render.main([str(score), "-o", str(tmp_path / "out"), "--jobs", "-1", "--quiet"]) == 2
    assert "--jobs -1" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_evaluate_refuses_negative_jobs_too(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    score = tmp_path / "rock.txt"
    score.write_text(ROCK)
    assert evaluate.main([str(score), "--jobs", "-2", "--quiet"]) == 2
    assert "--jobs -2" in capsys.readouterr().err


def _render(score: Path, out: Path, jobs: int) -> Path:
    assert render.main([str(score), "-o", str(out), "--jobs", str(jobs), "--segment", "5", "--quiet"]) == 0
    return out


@pytest.mark.slow
def test_segmented_render_plays_every_note_as_one_performance(tmp_path: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    score = tmp_path / "rock.txt"
    score.write_text(ROCK)
    out = _render(score, tmp_path / "two", 2)
    report = json.loads((out / "report.json").read_text())
    count = len(plan_segments(report["duration_s"], 5.0, 3.0))
    assert count >= 3
    assert report["physics"]["segments"] == {"count": count, "segment_s": 5.0, "warmup_s": 3.0, "jobs": 2}
    audio, sr = sf.read(out / "performance.wav")
    assert abs(len(audio) / sr - report["duration_s"]) < 0.02
    with (out / "impacts.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    times = [float(r["time"]) for r in rows]
    assert times == sorted(times) and times[-1] > 10.0  # the later segments' impacts are there
    assert sorted(int(r["seq"]) for r in rows) == list(range(len(rows)))  # numbered once across segments
    bvh = (out / "performance.bvh").read_text()
    frames, frame_s = int(bvh.split("Frames:")[1].split()[0]), float(bvh.split("Frame Time:")[1].split()[0])
    assert abs(frames * frame_s - report["duration_s"]) < 0.05  # no gap at a seam
    capsys.readouterr()
    assert evaluate.main([str(out), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)["files"][0]
    assert result["notes"] == 78
    assert result["f_measure"]["25ms"] >= 0.99  # the seams cost no note
    assert result["timing_ms"]["median_abs"] <= 3.0 and result["timing_ms"]["p95_abs"] <= 10.0
    # the cut does not depend on the number of processes: three give the same files
    again = _render(score, tmp_path / "three", 3)
    assert (again / "impacts.csv").read_bytes() == (out / "impacts.csv").read_bytes()
    assert (again / "performance.wav").read_bytes() == (out / "performance.wav").read_bytes()


def test_a_segment_keeps_what_is_about_its_own_window() -> None:
    from batteur.segments import _SoundCollector

    kept: list = []
    sound = _SoundCollector(Segment(1, 5.0, 10.0, 2.0, 10.25), kept)
    sound.handle(_impact(0, 4.99), 5.01, "interaction")  # struck in the lead-in, heard after: the last one's
    sound.handle(_impact(1, 5.0), 5.002, "interaction")
    sound.handle(_end(1, 5.0), 10.003, "interaction")  # its end comes after the window: still this one's
    sound.handle(_impact(2, 10.0), 10.001, "interaction")
    assert [(m.seq, type(m).__name__) for _, _, _, m in kept] == [(1, "Impact"), (1, "ImpactEnd")]


def test_a_worker_is_sent_only_its_segments_part_of_the_plan(tmp_path: Path) -> None:
    """Each worker was sent the whole plan and kept it from its lead-in to the piece's end (0.6 MB a second of
    music in every worker); its part samples as the whole plan wherever its drummer samples it."""
    import pickle

    from batteur.segments import JOIN_S, segment_plan
    from common.kit import load_kit

    score = tmp_path / "rock.txt"
    bar = "HH |x.x.x.x.x.x.x.x.|\nSN |....X.......X...|\nBD |x.......x.x.....|"
    score.write_text("tempo 100\nmeter 4/4\n" + "\n\n".join([bar] * 24))  # about 58 s
    kit = load_kit("default")
    opts = render.RenderOptions()
    _, _, plan = render.prepare(score, kit, opts)
    offset = opts.settle_s - plan.start_time
    segments = plan_segments(plan.end_time + offset + opts.latency_s + opts.tail_s, 5.0, 3.0)
    assert len(segments) >= 10
    whole = len(pickle.dumps(plan))
    for seg in segments:
        part = segment_plan(plan, seg, offset)
        assert len(pickle.dumps(part)) < whole / 3, seg
        assert (part.start_time, part.end_time) == (plan.start_time, plan.end_time)  # rig times map as before
        joined = plan if seg.index == 0 else plan.from_time(seg.run_from_s + JOIN_S - offset)
        times = np.arange(seg.run_from_s, seg.run_to_s + 1e-9, 0.001) - offset  # every step it simulates
        for limb, traj in joined.trajectories.items():
            assert part.trajectories[limb].times[0] == traj.times[0]  # joins where the whole plan's would
            for got, want in zip(part.trajectories[limb].sample_many(times), traj.sample_many(times), strict=True):
                assert np.array_equal(got, want), (seg, limb)
        assert joined.head is not None and part.head is not None
        for t in times[::10]:
            assert np.array_equal(part.head.sample(t)[0], joined.head.sample(t)[0]), (seg, t)
        needed = [s for s in joined.strokes if s.time <= seg.run_to_s - offset]
        assert part.strokes[:len(needed)] == needed and set(map(id, part.strokes)) <= set(map(id, joined.strokes))
