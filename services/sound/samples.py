"""The shipped recorded samples (services/sound/samples/, CC BY 3.0, see CREDITS.md there)."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import numpy.typing as npt
import soundfile as sf
from scipy.signal import resample_poly

from common.input_file import NO_SUCH_FILE, file_problem

log = logging.getLogger(__name__)

SAMPLES_DIR = Path(__file__).parent / "samples"

SAMPLE_TRIM_DB: dict[str, float] = {
    "kick": -13.3, "snare": -1.0, "rim": -19.9, "rim/rimshot": 0.0, "hightom": -14.4, "midtom": -10.9,
    "floortom": -5.3, "crash": -3.4, "ride": -12.5, "ridebell": 0.6, "china": -6.8, "hihat_open": 1.6,
    "cowbell": -4.0,
}
"""Level of each shipped sample, dB (``name/zone``: played for that zone), so that a strike sounds as loud as the
same strike of the modal model (the default, whose level is calibrated): the mean difference of their RMS over the
first 200 ms, measured on the default kit at its strike points, 0.5-6 m/s (tests/sound/test_sound_model_levels.py
checks 1.5 dB). The crash's is shared with the splash, which plays it faster; the rim click's sample also plays
rimshots, as loud as a head stroke. Kick, ride, ride bell, china and open hi-hat moved with the modal model when its
contact came to give the kit's restitution (-1.4, -0.4, -0.7, -0.6, -0.5 dB). See docs/sound.md, "Sample playback
and signal-based synthesis"."""


def sample_trim(name: str, zone: str) -> float:
    """Linear gain of sample ``name`` played for a strike in ``zone`` (SAMPLE_TRIM_DB; 1 for one not measured)."""
    db = SAMPLE_TRIM_DB.get(f"{name}/{zone}", SAMPLE_TRIM_DB.get(name, 0.0))
    return float(10.0 ** (db / 20.0))


class SampleBank:
    """Mono samples by name (file stem), loaded lazily and resampled to ``sample_rate``.

    Parameters
    ----------
    sample_rate : int
        Output rate, Hz.
    directory : Path
        Folder of WAV files.
    """

    def __init__(self, sample_rate: int = 48000, directory: Path = SAMPLES_DIR) -> None:
        self.sr = int(sample_rate)
        self.directory = directory
        self._cache: dict[str, npt.NDArray[np.float64] | None] = {}

    def names(self) -> list[str]:
        return sorted(p.stem for p in self.directory.glob("*.wav"))

    def get(self, name: str) -> npt.NDArray[np.float64] | None:
        """Samples of ``name`` (float64, shape (n,)), or None when there is no such regular file (a folder, a
        device or a pipe of that name is logged as :func:`common.input_file.file_problem` says it)."""
        if name not in self._cache:
            path = self.directory / f"{name}.wav"
            problem = file_problem(path, "a WAV sample")
            if problem is not None:  # the strike is synthesised; a pipe is never opened (it would block the node)
                if problem != NO_SUCH_FILE:
                    log.warning("%s: %s", path, problem)  # once: the refusal is cached
                self._cache[name] = None
            else:
                data, rate = sf.read(path, dtype="float64", always_2d=True)
                mono = data.mean(axis=1)
                if int(rate) != self.sr:
                    g = np.gcd(int(rate), self.sr)
                    mono = resample_poly(mono, self.sr // g, int(rate) // g)
                self._cache[name] = np.ascontiguousarray(mono)
        return self._cache[name]
