"""Live recogniser core: audio blocks in, :class:`~common.messages.recogniser.DrumHit` messages out.

Deterministic and free of sockets, threads and wall clock (see :mod:`common.core`):
the node feeds it blocks of samples with the rig time of their first sample.
It computes the same band spectrogram frames as the offline path, the SuperFlux
candidate onsets of :func:`~services.recogniser.features.pick_onsets` (peak picking
looks one frame ahead), and classifies each candidate with the model's short-context
``live`` MLP (a strike of a class within ``SUPPRESS_S`` of the previous one of that
class is not sent again; strikes of different classes are not grouped into chords:
that would date some hits up to ``CHORD_S`` earlier, adding as much to their
latency), so a hit is known about
``(max(offsets) + 0.5) * HOP + N_FFT / 2`` samples (about 33 ms) after its onset.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from common.core import Outgoing
from common.messages import OscMessage
from common.messages.recogniser import DrumHit
from services.recogniser import features as F
from services.recogniser.audio import SAMPLE_RATE
from services.recogniser.classes import CLASSES
from services.recogniser.model import Model, load_model
from services.recogniser.transcribe import PEAK, SUPPRESS_S

HISTORY = F.PRE_AVG + 8
"""Frames of spectrum and detection function kept, frames."""


class LiveRecogniser:
    """Streaming drum recogniser.

    Parameters
    ----------
    model : the classifier (default: the shipped model)
    to : where hits are sent (a role or ``host:port``)
    start_time : rig time of the first sample fed, seconds
    gain : fixed input gain; None: scale by a running peak (decaying 6 dB per ``peak_halflife_s``)
    """

    ROLE: ClassVar[str] = "recogniser"
    rate_hz: float = 0.0

    def __init__(
        self,
        model: Model | None = None,
        to: str = "127.0.0.1:9900",
        start_time: float = 0.0,
        gain: float | None = None,
        peak_halflife_s: float = 30.0,
    ) -> None:
        self.clf = (model or load_model()).live
        self.to = to
        self.start_time = start_time
        self.gain = gain
        self._decay_per_sample = 0.5 ** (1.0 / (peak_halflife_s * SAMPLE_RATE))
        self._peak = 0.0
        self._lookahead = max(F.POST_MAX, max(self.clf.offsets), max(F.ODF_OFFSETS))
        self._buf = np.zeros(F.N_FFT // 2, np.float32)  # left padding as in band_spectrogram
        self._buf_start = -(F.N_FFT // 2)  # absolute sample index of _buf[0]
        self._n_samples = 0
        self._next_frame = 0
        self._spec = np.zeros((0, F.N_BANDS), np.float32)
        self._odf = np.zeros((0, len(F.GROUPS)), np.float32)
        self._hist_start = 0  # frame index of _spec[0]
        self._last_onset = -(10**9)
        self._last_hit = np.full(len(CLASSES), -np.inf)  # rig time of the last hit sent per class
        self.seq = 0
        self.onsets: list[int] = []
        """Frame indices of all onsets found (for tests and diagnostics)."""

    # Core protocol: the recogniser does not react to messages and has no periodic work.
    def handle(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        return []

    def step(self, now: float) -> list[Outgoing]:
        return []

    def feed(self, block: np.ndarray) -> list[Outgoing]:
        """Append mono samples at SAMPLE_RATE; return the hits now recognised."""
        x = np.asarray(block, np.float32).reshape(-1)
        if x.size == 0:
            return []
        if not np.all(np.isfinite(x)):
            x = np.nan_to_num(x, nan=0.0, posinf=0.0, neginf=0.0)
        if self.gain is None:
            self._peak = max(self._peak * self._decay_per_sample ** x.size, float(np.max(np.abs(x))))
            g = PEAK / self._peak if self._peak > 1e-4 else 1.0
        else:
            g = self.gain
        return self._push(x * g)

    def _push(self, scaled: np.ndarray) -> list[Outgoing]:
        """Append samples already scaled by the input gain; return the hits now recognised."""
        self._buf = np.concatenate([self._buf, scaled])
        self._n_samples += scaled.size
        out: list[Outgoing] = []
        # frame t needs absolute samples up to t * HOP + N_FFT / 2
        while self._next_frame * F.HOP + F.N_FFT // 2 <= self._n_samples:
            out += self._frame(self._next_frame)
            self._next_frame += 1
        # keep the samples the next frame needs
        keep_from = self._next_frame * F.HOP - F.N_FFT // 2
        if keep_from > self._buf_start:
            self._buf = self._buf[keep_from - self._buf_start :]
            self._buf_start = keep_from
        return out

    def flush(self) -> list[Outgoing]:
        """Finish the stream: it stays at its level, the mean of its last ``N_FFT // 2`` samples, long enough for
        the last onsets to be classified (zeros would step down from a tail resting away from zero, such as a
        file's silence moved off zero by the removal of its mean, and a step is heard as a strike)."""
        level = float(np.mean(self._buf[-(F.N_FFT // 2) :]))  # the buffer always holds that many
        return self._push(np.full(F.N_FFT + self._lookahead * F.HOP, level, np.float32))

    def _frame(self, t: int) -> list[Outgoing]:
        lo = t * F.HOP - F.N_FFT // 2 - self._buf_start
        band = F.band_frame(self._buf[lo : lo + F.N_FFT])
        lagged = self._spec[t - F.LAG - self._hist_start] if t - F.LAG >= self._hist_start else None
        odf = F.superflux_frame(band, lagged) if lagged is not None else np.zeros(len(F.GROUPS), np.float32)
        self._spec = np.concatenate([self._spec, band[None]])[-HISTORY:]
        self._odf = np.concatenate([self._odf, odf[None]])[-HISTORY:]
        self._hist_start = t + 1 - len(self._spec)
        c = t - self._lookahead  # the frame whose look-ahead is now complete
        if c < 0 or c - self._last_onset < F.COMBINE:
            return []
        if not F.is_peak(self._odf, c - self._hist_start, self.clf.delta):
            return []
        self._last_onset = c
        self.onsets.append(c)
        local = np.array([c - self._hist_start])
        feats = F.onset_features(self._spec, self._odf, local, self.clf.offsets)
        prob = self.clf.probabilities(feats)[0]
        vel = self.clf.velocities(feats)[0]
        when = self.start_time + max(0.0, c * F.HOP / SAMPLE_RATE + self.clf.time_offset_s)
        out = []
        for k in np.flatnonzero(self.clf.decide(prob[None])[0]):
            if when - self._last_hit[int(k)] < SUPPRESS_S:  # causal form of the offline suppression
                continue
            self._last_hit[int(k)] = when
            cls = CLASSES[int(k)]
            hit = DrumHit(seq=self.seq, time=when, note=cls.note, event_type=cls.event_type,
                          velocity=int(vel[k]), confidence=float(prob[k]))
            self.seq += 1
            out.append(Outgoing(hit, self.to))
        return out

    @property
    def peak(self) -> float:
        """The running peak the input gain follows (``gain`` None), full scale 1: 0.0 before any input, and with a
        fixed gain."""
        return self._peak

    @property
    def latency_s(self) -> float:
        """Audio needed after an onset before its hit is emitted, seconds (excluding block size and compute)."""
        return (self._lookahead * F.HOP + F.N_FFT // 2) / SAMPLE_RATE
