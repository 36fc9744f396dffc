"""A render's memory does not grow with the piece: the WAV, impacts.csv and the BVH are written as they are
rendered (batteur/render.py StreamedOutputs), into the staging directory, with the bytes the whole-piece writers
gave; the segmented render's parent plays each segment as soon as those before it are in."""

from __future__ import annotations

import math
import random
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from batteur import render
from batteur.impact_log import ImpactCsvStream, ImpactLog, write_impacts_csv
from batteur.segments import SegmentResult, _Merger, merge
from common.messages import Impact
from common.messages.interaction import ImpactEnd
from services.graphics.export.bvh import BvhStream, write_bvh
from services.graphics.figure import synthetic_performance
from services.graphics.sequence import PoseSequence

HERE = Path(__file__).parent
SCORE = HERE / "short_groove.txt"


def _physics_like(seconds: float) -> PoseSequence:
    """Poses as physics sends them: on whole 1 ms steps, about 60 a second (17 and 16 ms apart)."""
    smooth = synthetic_performance(duration=seconds, rate_hz=240.0)[0]
    times = np.unique(np.round(np.arange(0.0, seconds, 1 / 60), 3)) + 0.5
    values = np.stack([smooth.sample(float(t - 0.5)) for t in times])
    return PoseSequence(smooth.names, times, values)


def test_the_streamed_bvh_is_write_bvhs_file_holding_one_chunk(tmp_path: Path) -> None:
    sequence = _physics_like(4.0)
    write_bvh(sequence, tmp_path / "whole.bvh", rate_hz=60.0)
    stream = BvhStream(tmp_path / "streamed.bvh", 60.0, chunk_frames=16)
    stream.restart(list(sequence.names))
    for t, frame in zip(sequence.times, sequence.values, strict=True):
        stream.add(float(t), frame)
    frames = stream.finish()
    assert (tmp_path / "streamed.bvh").read_bytes() == (tmp_path / "whole.bvh").read_bytes()
    assert frames == len(sequence.resample(60.0).times) == 239
    assert stream.peak_held_frames == 16  # written 16 frames at a time
    assert sorted(p.name for p in tmp_path.iterdir()) == ["streamed.bvh", "whole.bvh"]  # its rows' file is gone


def test_a_new_skeleton_starts_the_streamed_bvh_again_and_a_bad_pose_writes_none(tmp_path: Path) -> None:
    sequence = _physics_like(1.0)
    stream = BvhStream(tmp_path / "a.bvh", 60.0, chunk_frames=8)
    stream.restart(["other"])
    stream.add(0.1, np.zeros((1, 7)))
    stream.restart(list(sequence.names))  # only the newest skeleton's poses count, as PerformanceRecorder's
    for t, frame in zip(sequence.times, sequence.values, strict=True):
        stream.add(float(t), frame)
    stream.finish()
    write_bvh(sequence, tmp_path / "whole.bvh", rate_hz=60.0)
    assert (tmp_path / "a.bvh").read_bytes() == (tmp_path / "whole.bvh").read_bytes()
    bad = BvhStream(tmp_path / "b.bvh", 60.0)
    bad.restart(list(sequence.names))
    bad.add(0.0, sequence.values[0])
    bad.add(0.1, np.full_like(sequence.values[0], np.nan))  # a PoseSequence refuses it: no BVH, as before
    assert bad.finish() is None and not (tmp_path / "b.bvh").exists()


def _impact(seq: int, time: float, instrument: str = "snare") -> Impact:
    return Impact(seq=seq, time=time, instrument=instrument, zone="centre", r=0.2, theta=0.0, velocity=3.0,
                  impulse=0.0, peak_force=0.0, duration=0.0, part="left_stick_tip")


def _end(impact: Impact, impulse: float) -> ImpactEnd:
    return ImpactEnd(seq=impact.seq, time=impact.time, instrument=impact.instrument, kind="strike",
                     impulse=impulse, peak_force=40.0, duration=0.004, part="left_stick_tip")


def _arrivals(count: int, seed: int = 1) -> list[tuple[float, Any, str]]:
    """(rig time s, message, source) as interaction sends them: each impact at its first contact (a few ms
    late), its end a few ms later, or seconds later for a stick resting on a head; copies and stray ends too."""
    rng = random.Random(seed)
    out: list[tuple[float, Any, str]] = []
    t = 0.0
    for seq in range(count):
        t += rng.choice([0.0, 0.05, 0.15, 0.3])  # simultaneous strikes too (same time, other instrument)
        impact = _impact(seq, round(t, 3), rng.choice(["snare", "kick", "hihat"]))
        sent = impact.time + rng.choice([0.001, 0.002])
        out.append((sent, impact, "interaction"))
        out.append((sent + 0.001, impact, "interaction"))  # a redundant copy
        if seq < count - 3:  # the last impacts' contacts go on to the end of the render: no end
            # a stick resting on a head, now and then: its end comes seconds after later impacts
            held = 12.0 if seq % 500 == 0 else 4.0 if seq % 17 == 0 else 0.005
            out.append((sent + held, _end(impact, 0.01 + seq * 1e-4), "interaction"))
    out.append((t, _end(_impact(10**6, 1.0), 0.1), "interaction"))  # an end without its impact
    out.sort(key=lambda e: e[0])
    return out


def test_streamed_impacts_csv_is_the_whole_logs_file_holding_a_few_seconds(tmp_path: Path) -> None:
    arrivals = _arrivals(3000)  # about 7 minutes
    log = ImpactLog()
    stream = ImpactCsvStream(tmp_path / "streamed.csv")
    for now, message, source in arrivals:
        log.add(message, source)
        stream.add(message, now, source)
    assert stream.finish() == len(log.impacts) == 3000
    write_impacts_csv(log.sorted(), tmp_path / "whole.csv")
    assert (tmp_path / "streamed.csv").read_bytes() == (tmp_path / "whole.csv").read_bytes()
    assert stream.unmatched_ends == log.unmatched_ends == 1
    # at most the impacts of WAIT_S + HOLD_S (11 s, 8 a second here) behind a resting stick, not the piece's 3000
    assert stream.peak_held < 11 * 8 * 1.5
    assert sorted(p.name for p in tmp_path.iterdir()) == ["streamed.csv", "whole.csv"]


def test_an_impact_arriving_behind_written_rows_still_takes_its_place(tmp_path: Path) -> None:
    late = _impact(1, 0.5)
    arrivals = [(1.0, _impact(0, 1.0), ""), (1.0, _end(_impact(0, 1.0), 0.1), ""), (3.0, _impact(2, 2.9), ""),
                (3.1, late, ""), (3.2, _end(late, 0.2), "")]  # 2.6 s behind its time: after row 0 was written
    log, stream = ImpactLog(), ImpactCsvStream(tmp_path / "streamed.csv")
    for now, message, source in arrivals:
        log.add(message, source)
        stream.add(message, now, source)
    stream.finish()
    write_impacts_csv(log.sorted(), tmp_path / "whole.csv")
    assert (tmp_path / "streamed.csv").read_bytes() == (tmp_path / "whole.csv").read_bytes()


def _sent(index: int, times: list[float]) -> SegmentResult:
    return SegmentResult(index, [(t, "interaction", "sound", _impact(k, t)) for k, t in enumerate(times)], 0, {}, 0.0)


def test_the_segments_merged_as_they_come_are_merged_as_a_whole() -> None:
    results = [_sent(0, [0.1, 0.2, 5.1, 5.3]), _sent(1, [2.5, 5.0, 5.2, 9.9]), _sent(2, [7.0, 10.0, 10.1])]
    run_from = [0.0, 2.0, 7.0]  # every message of segment k is sent from its run_from_s on
    merger = _Merger()
    pieces = []
    for k, result in enumerate(results):
        merger.add(result)
        before = run_from[k + 1] if k + 1 < len(results) else math.inf
        pieces += merger.release(before)
        assert all(now >= before for now, *_ in merger._held)  # what is held is after what was played
    assert pieces == merge(results)
    assert [getattr(m, "seq", None) for *_, m in pieces] == list(range(11))


@pytest.mark.slow
def test_a_render_writes_its_outputs_as_it_goes(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    seen: list[tuple[float, int, int]] = []  # (rig time s, WAV samples written, BVH frames) during the run
    streams: list[render.StreamedOutputs] = []
    made = render.StreamedOutputs

    def spy(*args: Any, **kwargs: Any) -> render.StreamedOutputs:
        streams.append(made(*args, **kwargs))
        return streams[-1]

    monkeypatch.setattr(render, "StreamedOutputs", spy)
    opts = render.RenderOptions()
    kit = render.load_kit("default")
    prepared = render.prepare(SCORE, kit, opts)

    def run_score(*args: Any, **kwargs: Any) -> render.ScoreRender:
        outputs = kwargs["outputs"]

        def progress(t: float, total: float) -> None:
            if outputs.wav is not None and outputs.bvh is not None:
                seen.append((t, outputs.wav.written, outputs.bvh.frames))

        return real_run_score(*prepared, kit, opts, on_progress=progress, outputs=outputs)

    real_run_score = render.run_score
    monkeypatch.setattr(render, "run_score", run_score)
    report = render.render_score(SCORE, tmp_path / "out", opts, quiet=True)
    outputs = streams[0]
    assert outputs.wav is not None and outputs.bvh is not None
    # sound's blocks went to the file a second at a time as they were rendered: the WAV follows the clock
    middle = [(t, samples, frames) for t, samples, frames in seen if 2.0 < t < report["duration_s"] - 1.0]
    assert middle and all(-1.1 < samples / 48000 - t < 0.1 for t, samples, _ in middle)
    assert all(frames > 0 for *_, frames in middle)
    assert outputs.wav.buffer_frames == 48000 and outputs.bvh.peak_held_frames <= outputs.bvh.chunk_frames
    assert outputs.wav.frames / 48000 == pytest.approx(report["duration_s"], abs=0.01)
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [
        "impacts.csv", "performance.bvh", "performance.wav", "report.json", "score.txt"]


@pytest.mark.slow
def test_a_render_given_up_while_writing_leaves_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    class CtrlCAfterTwoSeconds:
        def __init__(self, *args: Any, **kwargs: Any) -> None:
            pass

        def update(self, t: float) -> None:
            if t > 2.0:  # the WAV, impacts and motion are being written by now
                raise KeyboardInterrupt

        def close(self, finished: bool = True) -> None:
            pass

    monkeypatch.setattr(render, "Progress", CtrlCAfterTwoSeconds)
    new = tmp_path / "new"
    assert render.main([str(SCORE), "-o", str(new), "--quiet"]) == render.INTERRUPTED
    assert not new.exists()
    kept = tmp_path / "kept"
    kept.mkdir()
    (kept / "mine.txt").write_text("not the render's")
    assert render.main([str(SCORE), "-o", str(kept), "--quiet"]) == render.INTERRUPTED
    assert [p.name for p in kept.iterdir()] == ["mine.txt"]  # no staging left, no file half written
