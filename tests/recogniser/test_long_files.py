"""Long recordings: reading and resampling an hour (the default --max-duration) took 4 GB of memory before the
first progress line (a 48 kHz file resampled in float64 all at once, beside two float32 copies of it). Resampling
block by block gives the same samples in a fraction of it."""

from __future__ import annotations

import tracemalloc
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf
from scipy.signal import resample_poly

from services.recogniser.audio import load_audio, resample


@pytest.mark.parametrize(("rate_in", "rate_out"), [(48000, 44100), (44100, 48000), (22050, 44100), (96000, 44100),
                                                    (48000, 8000), (8000, 44100), (44100, 22050), (11025, 44100)])
@pytest.mark.parametrize("n", [1, 999, 12345])
def test_resampling_by_blocks_gives_the_samples_of_one_pass(rate_in: int, rate_out: int, n: int) -> None:
    signal = np.random.default_rng(n).standard_normal(n).astype(np.float32)
    whole = resample(signal, rate_in, rate_out, block=10**9)  # one block: resample_poly over it all
    up, down = rate_out, rate_in
    assert np.array_equal(whole, resample_poly(signal.astype(np.float64), up, down).astype(np.float32))
    for block in (1, 257, 4096):  # blocks shorter than the filter, and than one period of the ratio
        assert np.array_equal(resample(signal, rate_in, rate_out, block=block), whole), block


def _peak_bytes(run: Callable[[], object]) -> int:
    """The most memory numpy and Python held at once while ``run`` ran, bytes."""
    tracemalloc.start()
    try:
        run()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_resampling_a_long_signal_holds_no_float64_copy_of_it() -> None:
    signal = np.random.default_rng(0).standard_normal(6_000_000).astype(np.float32)  # 125 s at 48 kHz, 24 MB
    peak = _peak_bytes(lambda: resample(signal, 48000, 44100))
    assert peak < 2.5 * signal.nbytes  # the result (0.92 of it) and one block; was 3.8x: float64 in and out


def test_reading_a_long_file_takes_under_four_times_its_float32_size(tmp_path: Path) -> None:
    n = 6_000_000
    wav = tmp_path / "long.wav"
    sf.write(wav, 0.5 * np.random.default_rng(0).standard_normal(n), 48000, subtype="PCM_16")
    peak = _peak_bytes(lambda: load_audio(wav, sample_rate=44100))
    assert peak < 4 * n * 4  # was 5.8x: the audio, its copy less the mean, |copy|, then float64 in and out
