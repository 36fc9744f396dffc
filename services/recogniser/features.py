"""Spectral features: log-frequency spectrogram, SuperFlux onset function, peak picking, onset context.

All at :data:`~services.recogniser.audio.SAMPLE_RATE` (22,050 Hz). Frame ``t`` is
a Hann window of :data:`N_FFT` samples centred on sample ``t * HOP``, so frame
times are ``t * HOP / SAMPLE_RATE`` seconds (about 100 frames per second).

The onset detection function is SuperFlux (Böck and Widmer, DAFx 2013): the
positive difference between a log-magnitude band spectrum and a frequency-wise
maximum-filtered copy of the spectrum ``LAG`` frames earlier, summed over bands.
It is computed separately in three band groups (kick, snare/tom, cymbal
ranges) so that a soft note under a ringing drum of another range still makes a
peak; the candidates are the union of the groups' peaks, kept permissive: the
live classifier rejects false ones. Peak picking looks one frame ahead only, so the
streaming core finds exactly the onsets this module finds offline. (Offline
transcription does not use these candidates: its network, :mod:`~services.recogniser.framenet`,
scores every frame.)
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import cache

import numpy as np
from scipy.ndimage import maximum_filter1d

from services.recogniser.audio import SAMPLE_RATE

N_FFT = 1024
"""Analysis window, samples (46 ms)."""
HOP = 220
"""Hop between frames, samples (about 10 ms)."""
FPS = SAMPLE_RATE / HOP
"""Frames per second."""
HOP_RANGE = (32, 1024)
"""Hops a trained network may use, samples (1.5-46 ms)."""
N_BANDS = 48
"""Log-spaced triangular bands, 40 Hz to 10.5 kHz."""
F_MIN_HZ = 40.0
"""Lowest band edge, Hz."""
F_MAX_HZ = 10500.0
"""Highest band edge of the :data:`N_BANDS` bands at :data:`SAMPLE_RATE`, Hz."""
LAG = 1
"""SuperFlux lag, frames."""
GROUPS = ((0, 12), (12, 28), (28, 48))
"""Band groups with their own detection function: about 40-150 Hz, 150-960 Hz, 960 Hz-10.5 kHz."""
MAX_SIZE = 3
"""SuperFlux maximum filter width across bands."""
PRE_MAX = 1
"""Peak picking: the onset must be the maximum of this many frames before it ..."""
POST_MAX = 1
"""... and of this many frames after it (the look-ahead, frames)."""
PRE_AVG = 10
"""Peak picking: moving-average window before the onset, frames."""
COMBINE = 2
"""Minimum distance between two onsets, frames."""
LOG_MUL = 1000.0
"""Log compression: log10(1 + LOG_MUL * magnitude)."""


@dataclass(frozen=True)
class Bands:
    """The band analysis a network reads: audio at ``sample_rate`` (Hz) in ``n`` log-spaced triangular bands
    from :data:`F_MIN_HZ` to ``f_max_hz``. Analysis windows and hops are counted in samples at that rate."""

    sample_rate: int = SAMPLE_RATE
    n: int = N_BANDS
    f_max_hz: float = F_MAX_HZ

    def __post_init__(self) -> None:
        if not 8000 <= self.sample_rate <= 192000:
            raise ValueError(f"band analysis at {self.sample_rate} Hz (expected 8,000..192,000)")
        if self.n < 8 or self.n % 4:
            raise ValueError(f"{self.n} bands (expected a multiple of 4, at least 8: the network halves them twice)")
        if not 4 * F_MIN_HZ < self.f_max_hz < self.sample_rate / 2:
            raise ValueError(f"highest band edge {self.f_max_hz:g} Hz (expected {4 * F_MIN_HZ:g} Hz to below "
                             f"half of {self.sample_rate} Hz)")

    def samples(self, n_at_base_rate: int) -> int:
        """Samples at this rate lasting as long as ``n_at_base_rate`` samples at :data:`SAMPLE_RATE`."""
        return round(n_at_base_rate * self.sample_rate / SAMPLE_RATE)


NARROW = Bands()
"""The recogniser's analysis until 5 Dec (and the live path's): 22,050 Hz, 48 bands up to 10.5 kHz."""
WIDE = Bands(44100, 56, 18000.0)
"""44,100 Hz, 56 bands up to 18 kHz: hi-hats reach far above 10.5 kHz (the held-out kit's, its pedal chick's
above all, lie mostly there), where every kit's snare is 7-16 dB weaker than below; below it a chick and a snare
are alike (docs/recogniser-history.md, "Recipe 5")."""


@cache
def band_matrix(n_fft: int = N_FFT, bands: Bands = NARROW) -> np.ndarray:
    """Triangular log-frequency filterbank of an ``n_fft``-sample window at ``bands.sample_rate``, shape
    (n_fft // 2 + 1, bands.n) (each band averages its bins; a band narrower than the bin spacing takes its
    nearest bin)."""
    n_bins = n_fft // 2 + 1
    freqs = np.linspace(0, bands.sample_rate / 2, n_bins)
    edges = np.geomspace(F_MIN_HZ, bands.f_max_hz, bands.n + 2)
    bins = np.searchsorted(freqs, edges)
    fb = np.zeros((n_bins, bands.n), dtype=np.float32)
    for b in range(bands.n):
        lo, mid, hi = bins[b], bins[b + 1], bins[b + 2]
        mid = max(mid, lo + 1)
        hi = max(hi, mid + 1)
        fb[lo:mid, b] = np.linspace(0.0, 1.0, mid - lo, endpoint=False)
        fb[mid:hi, b] = np.linspace(1.0, 0.0, hi - mid, endpoint=False)
        fb[:, b] /= max(float(fb[:, b].sum()), 1e-9)
    return fb


def full_rate_hz(bands: Bands) -> float:
    """The lowest sample rate whose audio reaches into every band of ``bands``, Hz: twice the lower edge of its top
    band (the edges of :func:`band_matrix`). Audio sampled below it leaves the top bands empty: for :data:`WIDE`,
    about 29 kHz, so a 22,050 Hz file lacks the bands above 11 kHz where hi-hats are told from snares."""
    edges = np.geomspace(F_MIN_HZ, bands.f_max_hz, bands.n + 2)
    return 2.0 * float(edges[bands.n - 1])


@cache
def window(n_fft: int = N_FFT) -> np.ndarray:
    """Hann window of ``n_fft`` samples, scaled by ``N_FFT / n_fft`` so that a steady tone has the same band
    magnitude whatever the window length."""
    return (np.hanning(n_fft) * (N_FFT / n_fft)).astype(np.float32)


BANDS = band_matrix()
WINDOW = window()


def n_frames(n_samples: int, hop: int = HOP) -> int:
    """Number of frames of ``hop`` samples for a signal of ``n_samples`` samples."""
    return n_samples // hop + 1


def frame_times(n: int, hop: int = HOP) -> np.ndarray:
    """Centre times of frames 0..n-1 of ``hop`` samples, seconds."""
    return np.arange(n) * (hop / SAMPLE_RATE)


def band_spectrogram(
    signal: np.ndarray, progress: Callable[[float], None] | None = None, chunk_frames: int = 4096,
    n_fft: int = N_FFT, hop: int = HOP, bands: Bands = NARROW, hold_edges: bool = False,
) -> np.ndarray:
    """Log-magnitude band spectrogram.

    Parameters
    ----------
    signal : np.ndarray [shape=(n,)], mono at ``bands.sample_rate`` (default :data:`SAMPLE_RATE`)
    progress : called with the fraction done (0..1) after each chunk
    chunk_frames : frames computed per chunk (bounds memory)
    n_fft : analysis window, samples (frame ``t`` is still centred on sample ``t * hop``)
    hop : samples between frames (default :data:`HOP`, 10 ms at :data:`SAMPLE_RATE`)
    bands : the band analysis (default :data:`NARROW`: 48 bands to 10.5 kHz)
    hold_edges : the frames reaching past the signal's ends see it stay at its level there, the mean of its first
        and last ``n_fft // 2`` samples (default: zeros; a signal resting away from zero at its ends, such as a
        silent lead-in moved off zero by the removal of the mean, would then step there, and a step sounds like a
        kick; the mean, not the edge sample, so that a tail cut while ringing adds no constant)

    Returns
    -------
    np.ndarray [shape=(n_frames(n, hop), bands.n), dtype=float32]
    """
    x = np.asarray(signal, dtype=np.float32)
    pad = n_fft // 2
    first, last = (float(np.mean(x[:pad])), float(np.mean(x[-pad:]))) if hold_edges and len(x) else (0.0, 0.0)
    x = np.concatenate([np.full(pad, first, np.float32), x, np.full(pad + hop, last, np.float32)])
    total = n_frames(len(signal), hop)
    out = np.empty((total, bands.n), dtype=np.float32)
    frames = np.lib.stride_tricks.sliding_window_view(x, n_fft)[::hop]
    win, fb = window(n_fft), band_matrix(n_fft, bands)
    for start in range(0, total, chunk_frames):
        stop = min(total, start + chunk_frames)
        mag = np.abs(np.fft.rfft(frames[start:stop] * win, axis=1)).astype(np.float32)
        out[start:stop] = np.log10(1.0 + LOG_MUL * (mag @ fb))
        if progress is not None:
            progress(stop / total)
    return out


def multi_spectrogram(
    signal: np.ndarray, windows: Sequence[int], progress: Callable[[float], None] | None = None, hop: int = HOP,
    bands: Bands = NARROW, hold_edges: bool = False,
) -> np.ndarray:
    """Band spectrograms of several analysis windows (:func:`band_spectrogram`; ``hold_edges`` as there), same
    frames of ``hop`` samples.

    Returns
    -------
    np.ndarray [shape=(n_frames(n, hop), bands.n, len(windows)), dtype=float32]
    """
    out = np.empty((n_frames(len(signal), hop), bands.n, len(windows)), np.float32)
    for i, n_fft in enumerate(windows):
        out[:, :, i] = band_spectrogram(signal, n_fft=n_fft, hop=hop, bands=bands, hold_edges=hold_edges,
                                        progress=part_progress(progress, i, len(windows)))
    return out


LEVEL_PERCENTILE = 95.0
"""A band's long-term level (:func:`band_levels`): this percentile of its values over a file's frames (its loud
frames, not its silences)."""
MAX_LEVEL_SHIFT = 1.5
"""The largest level change :func:`match_level` makes, in log10 of magnitude (+-30 dB)."""


def band_levels(spec: np.ndarray) -> np.ndarray:
    """Long-term level of each band (and input window) of a spectrogram (t, bands[, windows]): the
    :data:`LEVEL_PERCENTILE` percentile over its frames, in the spectrogram's units, shape (bands[, windows])."""
    return np.percentile(np.asarray(spec, np.float32), LEVEL_PERCENTILE, axis=0).astype(np.float32)


def scale_magnitudes(spec: np.ndarray, log10_gain: float) -> np.ndarray:
    """The spectrogram of the same audio with every band magnitude times ``10 ** log10_gain`` (a gain applied
    before the ``log10(1 + LOG_MUL x)`` compression: silence stays 0)."""
    x = np.asarray(spec, np.float32)
    return np.log10(1.0 + np.expm1(x * np.float32(np.log(10.0))) * np.float32(10.0**log10_gain)).astype(np.float32)


def match_level(spec: np.ndarray, reference: np.ndarray, alpha: float) -> np.ndarray:
    """Test-time level matching: ``spec`` (t, bands, windows) with one gain on every band so that the mean of its
    :func:`band_levels` moves ``alpha`` (0..1) of the way to the mean of ``reference`` (bands, windows; the same
    statistic over training renders), by at most :data:`MAX_LEVEL_SHIFT`. Peak normalisation leaves a file's level
    to its single loudest moment; this sets it by its loud frames, as the training files' were on average."""
    shift = alpha * float(np.mean(reference) - np.mean(band_levels(spec)))
    return scale_magnitudes(spec, min(MAX_LEVEL_SHIFT, max(-MAX_LEVEL_SHIFT, shift)))


def part_progress(progress: Callable[[float], None] | None, i: int, n: int) -> Callable[[float], None] | None:
    """A progress callback for part ``i`` of ``n`` equal parts of a job reporting to ``progress``."""
    if progress is None:
        return None
    report = progress

    def part(f: float) -> None:
        report((i + f) / n)

    return part


def band_frame(frame: np.ndarray) -> np.ndarray:
    """Log band spectrum of one frame of N_FFT samples, shape (N_BANDS,)."""
    mag = np.abs(np.fft.rfft(np.asarray(frame, np.float32) * WINDOW)).astype(np.float32)
    return np.log10(1.0 + LOG_MUL * (mag @ BANDS)).astype(np.float32)


def superflux(spec: np.ndarray) -> np.ndarray:
    """SuperFlux onset detection functions, one per band group (:data:`GROUPS`).

    Parameters
    ----------
    spec : np.ndarray [shape=(t, N_BANDS)], from :func:`band_spectrogram`

    Returns
    -------
    np.ndarray [shape=(t, len(GROUPS))], non-negative
    """
    ref = maximum_filter1d(spec, size=MAX_SIZE, axis=1)
    diff = np.zeros_like(spec)
    diff[LAG:] = np.maximum(spec[LAG:] - ref[:-LAG], 0.0)
    return np.stack([diff[:, a:b].sum(axis=1) for a, b in GROUPS], axis=1).astype(np.float32)


def superflux_frame(current: np.ndarray, lagged: np.ndarray) -> np.ndarray:
    """SuperFlux values (one per band group) of one frame given the band spectrum ``LAG`` frames earlier."""
    d = np.maximum(current - maximum_filter1d(lagged, size=MAX_SIZE), 0.0)
    return np.array([d[a:b].sum() for a, b in GROUPS], dtype=np.float32)


def peak_mask(odf: np.ndarray, delta: float) -> np.ndarray:
    """Candidate peaks of one detection function (shape (t,)): boolean mask, shape (t,).

    A frame is a candidate when it is the maximum of frames ``t - PRE_MAX .. t + POST_MAX``
    and exceeds the mean of frames ``t - PRE_AVG .. t`` by ``delta``.
    """
    n = len(odf)
    padded = np.concatenate([np.full(PRE_MAX, -np.inf), odf, np.full(POST_MAX, -np.inf)])
    win = np.lib.stride_tricks.sliding_window_view(padded, PRE_MAX + POST_MAX + 1)
    is_max = odf >= win.max(axis=1)
    csum = np.concatenate([[0.0], np.cumsum(odf, dtype=np.float64)])
    idx = np.arange(n)
    lo = np.maximum(0, idx - PRE_AVG)
    mean = (csum[idx + 1] - csum[lo]) / (idx + 1 - lo)
    return is_max & (odf > 0) & (odf >= mean + delta)


def is_peak(odf: np.ndarray, t: int, delta: float) -> bool:
    """Streaming form of :func:`peak_mask` for frame ``t`` of ``odf`` (shape (t, groups)); needs ``t + POST_MAX``."""
    window = odf[max(0, t - PRE_MAX) : t + POST_MAX + 1]
    v = odf[t]
    mean = odf[max(0, t - PRE_AVG) : t + 1].mean(axis=0)
    return bool(np.any((v >= window.max(axis=0)) & (v > 0) & (v >= mean + delta)))


def pick_onsets(odf: np.ndarray, delta: float) -> np.ndarray:
    """Onset frames: the union of the peaks of every band group's function, at least ``COMBINE`` frames apart.

    Parameters
    ----------
    odf : np.ndarray [shape=(t, len(GROUPS))], from :func:`superflux`
    delta : threshold above the local mean

    Returns
    -------
    np.ndarray [shape=(k,), dtype=int], increasing frame indices
    """
    if odf.shape[0] == 0:
        return np.zeros(0, dtype=int)
    mask = np.zeros(odf.shape[0], dtype=bool)
    for g in range(odf.shape[1]):
        mask |= peak_mask(odf[:, g], delta)
    return combine(np.flatnonzero(mask))


def combine(candidates: np.ndarray) -> np.ndarray:
    """Keep candidates at least ``COMBINE`` frames after the previous kept one."""
    onsets: list[int] = []
    last = -(10**9)
    for t in candidates:
        if t - last >= COMBINE:
            onsets.append(int(t))
            last = int(t)
    return np.asarray(onsets, dtype=int)


def context(spec: np.ndarray, frames: np.ndarray, offsets: Sequence[int]) -> np.ndarray:
    """Stack the rows of ``spec`` (shape (t, d)) at ``frames + offset`` for each offset (zeros outside).

    Returns
    -------
    np.ndarray [shape=(len(frames), len(offsets) * d), dtype=float32]
    """
    d = spec.shape[1]
    if spec.shape[0] == 0 or len(frames) == 0:
        return np.zeros((len(frames), len(offsets) * d), np.float32)
    lo, hi = min(offsets), max(offsets)
    padded = np.concatenate([np.zeros((max(0, -lo), d), np.float32), spec, np.zeros((max(0, hi), d), np.float32)])
    shift = max(0, -lo)
    rows = [padded[np.asarray(frames, dtype=int) + o + shift] for o in offsets]
    return np.concatenate(rows, axis=1).astype(np.float32)


ODF_OFFSETS = (-1, 0, 1)
"""Detection-function frames added to the features around each onset."""
FLUX_OFFSETS = (0, 1)
"""Frames whose per-band positive spectral difference is added to the features (what just started)."""


def onset_features(spec: np.ndarray, odf: np.ndarray, frames: np.ndarray, offsets: Sequence[int]) -> np.ndarray:
    """Classifier input for onsets at ``frames``: band spectra at ``offsets``, the per-band positive
    difference to the previous frame at :data:`FLUX_OFFSETS` and the detection functions at :data:`ODF_OFFSETS`.

    Returns
    -------
    np.ndarray [shape=(len(frames), n_features(offsets))]
    """
    flux = np.maximum(np.diff(spec, axis=0, prepend=spec[:1]), 0.0)
    parts = [context(spec, frames, offsets), context(flux, frames, FLUX_OFFSETS), context(odf, frames, ODF_OFFSETS)]
    return np.concatenate(parts, axis=1)


def n_features(offsets: Sequence[int]) -> int:
    """Length of :func:`onset_features` rows for these spectrum offsets."""
    return (len(offsets) + len(FLUX_OFFSETS)) * N_BANDS + len(ODF_OFFSETS) * len(GROUPS)
