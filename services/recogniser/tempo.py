"""The tempo of a transcription, estimated from its strikes' times, for the MIDI file's tempo (its bars then line
up in a score editor, a DAW, ``batteur render`` and ``batteur compare``): note times stay exact whatever it is.

The strikes make a train of pulses weighted by their velocities (a kick with a hi-hat counts more than a ghost
note), smoothed by :data:`SMOOTH_S` for a human's timing; each beat period of :data:`RANGE_BPM` is scored by the
train's autocorrelation at 1 to :data:`COMB_BEATS` beats (a comb: a beat lines up with itself one, two, three and
four beats on, an offbeat or a swung eighth does not), and the best one is the tempo. Deterministic, numpy only.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

RANGE_BPM = (70.0, 180.0)
"""Tempos considered, BPM: a groove's beat is read in this range (a 60 BPM take is read at 120, a 200 BPM one at
100: the same bars, counted in half or double notes)."""
STEP_BPM = 0.1
"""The candidates' spacing, BPM."""
BIN_S = 0.005
"""The pulse train's resolution, seconds."""
SMOOTH_S = 0.02
"""Standard deviation of the Gaussian each strike is spread over, seconds (a drummer's timing is this loose)."""
COMB_BEATS = 4
"""Beats the comb reaches: the autocorrelation at 1..4 beat periods is summed."""
PRIOR_BPM = 120.0
"""The tempo preferred among those the comb scores alike (a beat at 150 BPM also lines up every two beats, as 75
BPM's would), BPM ..."""
PRIOR_OCTAVES = 1.5
"""... by a log-Gaussian weight of this width, octaves (as beat trackers do, Ellis 2007). 1.5: synthetic grooves
of 70-150 BPM, straight and swung, read at their tempo, 175 at half (1.0 read a straight 70 at 140)."""
MIN_STRIKES = 8
"""Fewer strike times than this give no tempo (as too short to tell)."""
MIN_BEATS = 4
"""A take shorter than this many beats of the tempo found (from its first strike to its last) gives none."""
MIN_REGULARITY = 0.35
"""The comb's mean normalised autocorrelation at the tempo found (1: every strike recurs exactly each beat) below
which the strikes are taken as too irregular to give one: strikes at random times score about 0.05-0.2, a played
groove (straight, swung, with fills) 0.5-0.9."""


def estimate_tempo(times_s: Sequence[float], weights: Sequence[float] | None = None) -> float | None:
    """The tempo of strikes at ``times_s`` (seconds, any order), BPM in :data:`RANGE_BPM` rounded to a whole BPM,
    or None when they are too few, too short (:data:`MIN_STRIKES`, :data:`MIN_BEATS`) or too irregular
    (:data:`MIN_REGULARITY`) to tell. ``weights``: each strike's weight (e.g. its velocity; default 1); strikes at
    the same time add up (a chord)."""
    t = np.asarray(times_s, dtype=np.float64)
    w = np.ones_like(t) if weights is None else np.asarray(weights, dtype=np.float64)
    if w.shape != t.shape:
        raise ValueError(f"estimate_tempo: {len(w)} weights for {len(t)} strike times")
    finite = np.isfinite(t) & np.isfinite(w) & (w >= 0)  # a NaN, an infinity or a negative weight says nothing
    t, w = t[finite], w[finite]
    if len(np.unique(np.round(t / BIN_S))) < MIN_STRIKES:
        return None
    t = t - t.min()
    span_s = float(t.max())
    lo, hi = RANGE_BPM
    reach = int(np.ceil(COMB_BEATS * 60.0 / lo / BIN_S)) + 2
    n = int(np.ceil(span_s / BIN_S)) + 1 + reach  # zero padding: the autocorrelation is not circular
    train = np.zeros(n)
    np.add.at(train, np.round(t / BIN_S).astype(np.int64), w)
    half = int(np.ceil(4 * SMOOTH_S / BIN_S))
    kernel = np.exp(-0.5 * (np.arange(-half, half + 1) * BIN_S / SMOOTH_S) ** 2)
    train = np.convolve(train, kernel, mode="same")
    spectrum = np.fft.rfft(train, 2 * n)
    acf = np.fft.irfft(spectrum * np.conj(spectrum), 2 * n)[: reach + 1]
    if acf[0] <= 0:
        return None
    span_bins = max(span_s / BIN_S, 1.0)
    lag = np.arange(len(acf))
    acf *= span_bins / np.maximum(span_bins - lag, 0.25 * span_bins)  # a lag overlaps less of a short take
    acf /= acf[0]
    bpms = np.arange(lo, hi + STEP_BPM / 2, STEP_BPM)
    periods_bins = 60.0 / bpms / BIN_S
    lags = periods_bins[:, None] * np.arange(1, COMB_BEATS + 1)[None, :]
    scores = np.interp(lags, np.arange(len(acf)), acf).mean(axis=1)
    prior = np.exp(-0.5 * (np.log2(bpms / PRIOR_BPM) / PRIOR_OCTAVES) ** 2)
    best = int(np.argmax(scores * prior))
    bpm = float(bpms[best])
    if scores[best] < MIN_REGULARITY or span_s < MIN_BEATS * 60.0 / bpm:
        return None
    return float(round(bpm))
