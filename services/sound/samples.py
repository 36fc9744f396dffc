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
