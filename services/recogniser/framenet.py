"""The offline recogniser network: a small convolutional network over the band spectrogram, run with NumPy.

For every spectrogram frame (10 ms, or 5 ms for a network trained so) it gives the probability that a strike of
each class starts there, the probability that a strike of any class does (the
"onset" output) and a velocity per class. Two 3x3 convolutions over time and
frequency (each followed by a 2:1 maximum over frequency) see a strike's local
shape wherever its energy sits, so a kit tuned differently looks alike; a stack
of dilated convolutions over time then sees about +-170 ms of context (what was
already ringing, what follows). Strikes are the activation peaks above a
per-class threshold (:meth:`FrameNet.detect`).

Batch normalisation is folded into the convolution weights when the trained
network is exported, so inference is convolutions, ReLUs, maxima and sigmoids.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from services.recogniser import features as F
from services.recogniser.classes import N_CLASSES

N_OUT = 2 * N_CLASSES + 1
"""Outputs per frame: N_CLASSES class activations, the onset activation, N_CLASSES velocities / 127."""
SNARE, HIHATS = 1, (2, 3)
"""Class indices of the snare and of the closed and open hi-hat (see :mod:`services.recogniser.classes`)."""
SNAP_MIN = 0.1
"""Onset-output peaks at least this high are the times class strikes may be moved to (``snap_frames``)."""


@dataclass
class Layer:
    """One convolution. ``kind`` 'conv2d': w (kt, kf, c_in, c_out) over (time, band); 'conv1d': w (kt, c_in, c_out)
    over time (the bands flattened into channels before the first one). ``pool``: maximum over this many
    neighbouring bands after the ReLU; ``residual``: the input is added to the output (same width)."""

    kind: str
    w: np.ndarray
    b: np.ndarray
    dilation: int = 1
    pool: int = 1
    relu: bool = True
    residual: bool = False

    @property
    def margin(self) -> int:
        """Context frames this layer needs on each side."""
        return (int(self.w.shape[0]) // 2) * self.dilation


def _conv2d(x: np.ndarray, w: np.ndarray, b: np.ndarray) -> np.ndarray:
    """'Same' 2-D convolution of x (t, bands, c_in) as one matrix product (im2col)."""
    kt, kf, c_in, c_out = w.shape
    t, nb, _ = x.shape
    xp = np.pad(x, ((kt // 2, kt // 2), (kf // 2, kf // 2), (0, 0)))
    cols = np.empty((t, nb, kt, kf, c_in), np.float32)
    for i in range(kt):
        for j in range(kf):
            cols[:, :, i, j] = xp[i : i + t, j : j + nb]
    return (cols.reshape(t * nb, -1) @ w.reshape(-1, c_out) + b).reshape(t, nb, c_out)


def _conv1d(x: np.ndarray, w: np.ndarray, b: np.ndarray, dilation: int) -> np.ndarray:
    """'Same' dilated convolution over time of x (t, c_in)."""
    kt, c_in, c_out = w.shape
    t = x.shape[0]
    half = (kt // 2) * dilation
    xp = np.pad(x, ((half, half), (0, 0)))
    cols = np.concatenate([xp[i * dilation : i * dilation + t] for i in range(kt)], axis=1)
    return cols @ w.reshape(-1, c_out) + b


@dataclass
class Network:
    """One convolutional network: its layers, the analysis windows (samples) of its input channels, the
    samples between its frames and the band analysis of its input (the windows and the hop count samples at
    ``bands.sample_rate``)."""

    layers: list[Layer]
    windows: tuple[int, ...] = (F.N_FFT,)
    hop: int = F.HOP
    bands: F.Bands = F.NARROW

    @property
    def margin(self) -> int:
        """Frames of context the network needs on each side of an output frame."""
        return sum(la.margin for la in self.layers)

    def logits(self, x: np.ndarray) -> np.ndarray:
        """Output logits (t, N_OUT) for input frames (t, N_BANDS, len(windows)) ('same' padding)."""
        for la in self.layers:
            if la.kind == "conv1d" and x.ndim == 3:
                x = x.transpose(0, 2, 1).reshape(x.shape[0], -1)  # channel-major, as torch's flatten
            y = _conv2d(x, la.w, la.b) if la.kind == "conv2d" else _conv1d(x, la.w, la.b, la.dilation)
            if la.relu:
                y = np.maximum(y, 0.0)
            if la.pool > 1:
                y = y.reshape(y.shape[0], y.shape[1] // la.pool, la.pool, y.shape[2]).max(axis=2)
            x = x + y if la.residual else y
        return x

    def sigmoids(self, x: np.ndarray, chunk_frames: int = 2048,
                 progress: Callable[[float], None] | None = None) -> np.ndarray:
        """Sigmoid outputs (t, N_OUT) for input frames (t, N_BANDS, len(windows)), padded with silence and run
        in chunks that overlap by the network's context (the result does not depend on ``chunk_frames``)."""
        t = x.shape[0]
        m = self.margin
        pad = np.zeros((m, *x.shape[1:]), np.float32)
        padded = np.concatenate([pad, x, pad])
        out = np.empty((t, N_OUT), np.float32)
        for a in range(0, t, chunk_frames):
            b = min(t, a + chunk_frames)
            logits = self.logits(padded[a : b + 2 * m])[m : m + b - a]
            out[a:b] = 1.0 / (1.0 + np.exp(-np.clip(logits, -60, 60)))
            if progress is not None:
                progress(b / t)
        return out


@dataclass
class FrameNet:
    """The framewise network (or an ensemble of networks) and its decision rule.

    ``layers`` and ``windows``: the (first) network's layers and the analysis windows (samples) of its input
    spectrograms, one input channel each (:func:`~services.recogniser.features.multi_spectrogram`);
    ``members``: further networks whose outputs are averaged with the first's (an ensemble; each reads its
    own windows);
    ``thresholds``: N_CLASSES + 1 activation thresholds (the last: the onset output; above 1: unused);
    ``peak_frames``: a strike is an activation maximum over +-this many frames; ``time_offset_s`` is
    added to frame times; ``chord_s``: strikes of different classes this close to the first of a group
    are given its time (see :func:`~services.recogniser.transcribe.group_chords`; 0: off).
    ``snap_frames``: a class strike is moved to the nearest onset-output peak (of at least :data:`SNAP_MIN`)
    within this many frames (0: off), so classes of one strike that peak a few frames apart share its time;
    ``hihat_snare``: a snare peak is dropped where a hi-hat activation within +-1 frame reaches its threshold
    and this ratio times it exceeds the snare activation (a hi-hat heard as a snare too; 0: off).
    ``subframe``: strike times fall between frames, at the vertex of a parabola through the peak and its two
    neighbours (:meth:`positions`), so two strikes 20-30 ms apart whose peaks are two frames apart are not
    taken for one chord, and times are finer than the frames.
    ``hop``: samples between frames (every network's; 220: 10 ms, 110: 5 ms at 22,050 Hz). ``peak_frames`` and
    ``snap_frames`` count these frames. ``bands``: the band analysis of the input (every network's; its
    sample rate is the rate of the audio :meth:`spectrogram` takes, the windows and the hop count samples at it).
    ``profile``: the long-term band levels (:func:`~services.recogniser.features.band_levels`, shape
    (bands.n, len(inputs))) of training renders, or None; ``level_match``: how far (0..1; 0: off) :meth:`adapt`
    moves a file's level towards the profile's before the network reads it (test-time adaptation to a kit's
    loudness; recogniser-history.md, "Test-time adaptation").
    """

    layers: list[Layer]
    thresholds: np.ndarray
    peak_frames: int = 1
    time_offset_s: float = 0.0
    chord_s: float = 0.02
    windows: tuple[int, ...] = (F.N_FFT,)
    members: list[Network] = field(default_factory=list)
    snap_frames: int = 0
    hihat_snare: float = 0.0
    subframe: bool = False
    hop: int = F.HOP
    bands: F.Bands = F.NARROW
    profile: np.ndarray | None = None
    level_match: float = 0.0

    def __post_init__(self) -> None:
        hops = {m.hop for m in self.members} - {self.hop}
        if hops:
            raise ValueError(f"an ensemble's networks must share their frames: hops {sorted(hops)} and {self.hop}")
        others = {m.bands for m in self.members} - {self.bands}
        if others:
            raise ValueError(f"an ensemble's networks must share their band analysis: {sorted(map(str, others))} "
                             f"and {self.bands}")

    @property
    def sample_rate(self) -> int:
        """Sample rate of the audio the network reads, Hz."""
        return self.bands.sample_rate

    @property
    def fps(self) -> float:
        """Frames per second of the outputs."""
        return self.bands.sample_rate / self.hop

    @property
    def networks(self) -> list[Network]:
        return [Network(self.layers, self.windows, self.hop, self.bands), *self.members]

    @property
    def inputs(self) -> tuple[int, ...]:
        """The analysis windows of the input spectrograms (every network's), increasing."""
        return tuple(sorted({w for n in self.networks for w in n.windows}))

    @property
    def margin(self) -> int:
        """Frames of context the whole network needs on each side of an output frame."""
        return max(n.margin for n in self.networks)

    def spectrogram(self, signal: np.ndarray, progress: Callable[[float], None] | None = None,
                    hold_edges: bool = False) -> np.ndarray:
        """The input for mono audio at :attr:`sample_rate`: (t, bands.n, len(inputs)), frames ``hop`` samples
        apart; ``hold_edges``: beyond its ends the audio stays at its level there, not zero
        (:func:`~services.recogniser.features.band_spectrogram`)."""
        return F.multi_spectrogram(signal, self.inputs, progress, self.hop, self.bands, hold_edges)

    def adapt(self, spec: np.ndarray) -> np.ndarray:
        """The network's input for a file's spectrograms (:meth:`spectrogram`): with ``level_match`` and a
        ``profile``, one gain on every band (:func:`~services.recogniser.features.match_level`); else ``spec``
        itself."""
        if self.level_match <= 0.0 or self.profile is None:
            return spec
        return F.match_level(spec, self.profile, self.level_match)

    def forward(self, spec: np.ndarray, chunk_frames: int = 2048,
                progress: Callable[[float], None] | None = None) -> np.ndarray:
        """Sigmoid outputs (t, N_OUT) for the input spectrograms (t, N_BANDS, len(inputs)) (:meth:`spectrogram`;
        (t, N_BANDS) with one window), the mean of the networks' outputs. The input is padded with silence;
        the result does not depend on ``chunk_frames``. ``progress``: called with the fraction done."""
        x = np.asarray(spec, np.float32)
        x = x[:, :, None] if x.ndim == 2 else x
        nets, inputs = self.networks, self.inputs
        out = np.zeros((x.shape[0], N_OUT), np.float32)
        for k, net in enumerate(nets):
            part = x[:, :, [inputs.index(w) for w in net.windows]]
            out += net.sigmoids(part, chunk_frames, F.part_progress(progress, k, len(nets)))
        return out / len(nets)

    def peaks(self, act: np.ndarray, threshold: float) -> np.ndarray:
        """Frames where ``act`` (t,) reaches ``threshold`` and is the maximum of +-peak_frames (the first of equals)."""
        w = self.peak_frames
        p = np.concatenate([np.full(w, -np.inf), act, np.full(w, -np.inf)])
        win = np.lib.stride_tricks.sliding_window_view(p, 2 * w + 1)
        keep = (act >= threshold) & (act >= win.max(axis=1)) & (act > win[:, :w].max(axis=1))
        return np.flatnonzero(keep)

    def detect(self, out: np.ndarray) -> list[tuple[int, int, int, float]]:
        """Strikes from :meth:`forward`'s outputs: (frame, class, MIDI velocity, probability), by frame.

        A class strikes at its activation peaks above its threshold (a snare peak under a hi-hat may be
        dropped: ``hihat_snare``). An onset-output peak above its threshold with no class strike within
        +-peak_frames is a strike of the class most probable there. With ``snap_frames``, strikes are then
        moved to the nearest onset-output peak (velocity and probability stay those of the class's own peak).
        """
        found: list[tuple[int, int, int, float]] = []
        vel = np.clip(np.rint(out[:, N_CLASSES + 1 :] * 127.0), 1, 127).astype(int)
        struck = np.zeros(out.shape[0], bool)
        for c in range(N_CLASSES):
            for t in self.peaks(out[:, c], float(self.thresholds[c])):
                if c == SNARE and self.hihat_snare > 0 and self._under_hihat(out, int(t)):
                    continue
                found.append((int(t), c, int(vel[t, c]), float(out[t, c])))
                struck[max(0, t - self.peak_frames) : t + self.peak_frames + 1] = True
        if self.thresholds[N_CLASSES] <= 1.0:
            for t in self.peaks(out[:, N_CLASSES], float(self.thresholds[N_CLASSES])):
                if not struck[t]:
                    c = int(np.argmax(out[t, :N_CLASSES]))
                    found.append((int(t), c, int(vel[t, c]), float(out[t, c])))
        if self.snap_frames > 0:
            found = self._snap(out, found)
        found.sort()
        return found

    def anchors(self, out: np.ndarray) -> np.ndarray:
        """Frames of the onset-output peaks of at least :data:`SNAP_MIN`: where ``snap_frames`` moves strikes."""
        return self.peaks(out[:, N_CLASSES], SNAP_MIN)

    def positions(self, out: np.ndarray, found: list[tuple[int, int, int, float]]) -> np.ndarray:
        """Frame positions (k,) of :meth:`detect`'s strikes, fractional with ``subframe`` (else their frames).

        A strike at an onset-output peak (where ``snap_frames`` moves strikes) is placed by the onset output,
        any other by its class's activation: ``t + (a - c) / (2 (a - 2b + c))`` for the activations a, b, c at
        frames t - 1, t, t + 1, within +-0.5 frame (t itself where the three do not bend down).
        """
        pos = np.array([t for t, _, _, _ in found], np.float64)
        if not self.subframe or not found:
            return pos
        anchors = set(self.anchors(out).tolist()) if self.snap_frames > 0 else set()
        last = out.shape[0] - 1
        for i, (t, c, _, _) in enumerate(found):
            if 0 < t < last:
                a, b, d = (float(v) for v in out[t - 1 : t + 2, N_CLASSES if t in anchors else c])
                bend = a - 2.0 * b + d
                if bend < 0.0:
                    pos[i] += min(0.5, max(-0.5, 0.5 * (a - d) / bend))
        return pos

    def _under_hihat(self, out: np.ndarray, t: int) -> bool:
        """Whether a hi-hat activation within +-1 frame of ``t`` reaches its threshold and, times
        ``hihat_snare``, exceeds the snare activation at ``t``."""
        near = out[max(0, t - 1) : t + 2, list(HIHATS)]
        hh = near[near >= self.thresholds[list(HIHATS)]]
        return bool(hh.size) and float(out[t, SNARE]) < self.hihat_snare * float(hh.max())

    def _snap(self, out: np.ndarray, found: list[tuple[int, int, int, float]]) -> list[tuple[int, int, int, float]]:
        """``found`` with each frame moved to the nearest onset-output peak within ``snap_frames`` (the earlier
        of two equally near), a class struck twice at one frame kept once (the more probable)."""
        anchors = self.anchors(out)
        if not len(anchors):
            return found
        best: dict[tuple[int, int], tuple[int, int, int, float]] = {}
        for t, c, v, p in found:
            i = int(np.searchsorted(anchors, t))
            near = min((int(anchors[k]) for k in (i - 1, i) if 0 <= k < len(anchors)), key=lambda a: abs(a - t))
            s = near if abs(near - t) <= self.snap_frames else t
            if (s, c) not in best or p > best[(s, c)][3]:
                best[(s, c)] = (s, c, v, p)
        return list(best.values())
