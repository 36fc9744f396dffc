"""``PoseSequence.resample``: the frames of a BVH or glTF export, each the sequence's own sample at its time."""

from __future__ import annotations

import numpy as np

from services.graphics.figure import synthetic_performance


def test_resample_gives_each_frame_the_sample_at_its_time_and_tells_its_progress() -> None:
    sequence, _ = synthetic_performance(duration=3.0)
    told: list[int] = []
    frames = sequence.resample(24.0, on_progress=told.append)
    times = sequence.resample_times(24.0)
    assert np.array_equal(frames.times, times) and len(times) == int(np.floor(sequence.duration * 24.0 + 1e-9)) + 1
    assert np.array_equal(frames.values, np.stack([sequence.sample(float(t)) for t in times]))
    assert told[0] == 0 and told[-1] == len(times)
