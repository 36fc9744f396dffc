"""Reading audio files for transcription: any sample rate, mono or stereo.

Files are read with soundfile (WAV, FLAC, OGG/Vorbis, AIFF, ...), mixed down
to mono and resampled to the rate asked for (default :data:`SAMPLE_RATE`) with a polyphase filter
(:func:`scipy.signal.resample_poly`).
"""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import numpy as np
import soundfile as sf
from scipy.signal import resample_poly

from services.recogniser.errors import AudioFileError

SAMPLE_RATE = 22050
"""Sample rate of the live path and the default of :func:`load_audio`, Hz (the offline network reads audio at its
own rate, :attr:`~services.recogniser.framenet.FrameNet.sample_rate`: 44,100 Hz for the shipped one)."""

MAX_DURATION_S = 3600.0
"""Longest file accepted by default, seconds (one hour)."""

SILENCE_PEAK = 10 ** (-70 / 20)
"""A file whose peak is below this (-70 dBFS) is called silent."""


def resample(signal: np.ndarray, sr_in: int, sr_out: int = SAMPLE_RATE) -> np.ndarray:
    """Resample a mono signal.

    Parameters
    ----------
    signal : np.ndarray [shape=(n,)]
    sr_in, sr_out : int, Hz

    Returns
    -------
    np.ndarray [shape=(round(n * sr_out / sr_in),), dtype=float32]
    """
    if sr_in == sr_out:
        return np.asarray(signal, dtype=np.float32)
    ratio = Fraction(sr_out, sr_in).limit_denominator(2000)
    out = resample_poly(np.asarray(signal, dtype=np.float64), ratio.numerator, ratio.denominator)
    return out.astype(np.float32)


def to_mono(data: np.ndarray) -> np.ndarray:
    """Average the channels of a (n,) or (n, channels) array to shape (n,)."""
    if data.ndim == 1:
        return data
    return np.mean(data, axis=1)


def load_audio(path: str | Path, max_duration_s: float = MAX_DURATION_S, sample_rate: int = SAMPLE_RATE
               ) -> np.ndarray:
    """Read an audio file as mono float32 at ``sample_rate`` Hz (default :data:`SAMPLE_RATE`).

    Parameters
    ----------
    path : audio file (WAV, FLAC, OGG, ...)
    max_duration_s : longer files are refused, seconds

    Returns
    -------
    np.ndarray [shape=(n,), dtype=float32], samples in [-1, 1]

    Raises
    ------
    AudioFileError
        the file is missing, unreadable, empty, silent or longer than ``max_duration_s``.
    """
    p = Path(path)
    if not p.exists():
        raise AudioFileError(f"{p}: no such file")
    if p.is_dir():
        raise AudioFileError(f"{p}: is a directory, not an audio file")
    try:
        info = sf.info(str(p))
    except Exception as exc:  # soundfile raises several types (LibsndfileError, RuntimeError, TypeError)
        raise AudioFileError(f"{p}: not a readable audio file (WAV, FLAC, OGG...): {exc}") from exc
    if info.frames <= 0 or info.samplerate <= 0:
        raise AudioFileError(f"{p}: the file holds no audio (0 samples)")
    duration = info.frames / info.samplerate
    if duration > max_duration_s:
        raise AudioFileError(
            f"{p}: {duration:.4g} s long, over the limit of {max_duration_s:.4g} s "
            "(cut the file, or raise the limit with --max-duration)"
        )
    try:
        data, sr = sf.read(str(p), dtype="float32", always_2d=False)
    except Exception as exc:
        raise AudioFileError(f"{p}: cannot decode the audio: {exc}") from exc
    mono = to_mono(np.asarray(data, dtype=np.float32))
    if mono.size == 0:
        raise AudioFileError(f"{p}: the file holds no audio (0 samples)")
    if not np.all(np.isfinite(mono)):
        raise AudioFileError(f"{p}: the audio holds NaN or infinite samples")
    if float(np.max(np.abs(mono))) < SILENCE_PEAK:
        raise AudioFileError(f"{p}: the audio is silent (peak below -70 dBFS); nothing to transcribe")
    return resample(mono, int(sr), sample_rate)
