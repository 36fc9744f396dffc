"""Choosing the offline network's decision thresholds on the validation kit (never on the held-out kit).

Each choice maximises the strike-level F-measure at 50 ms (mir_eval's onset matching,
pooled over the validation excerpts), the benchmark's measure: first every class's
threshold on its own strikes, then the onset output's threshold and the chord window
(with ``rules``, also how far class strikes move to onset-output peaks) on the
class-agnostic onsets, last (with ``rules``) the ratio that drops snare peaks under
hi-hat peaks on the snare strikes.
"""

from __future__ import annotations

import mir_eval
import numpy as np

from services.recogniser.classes import CLASS_NAMES, N_CLASSES
from services.recogniser.features import FPS
from services.recogniser.framenet import SNARE, FrameNet
from services.recogniser.training.frames import FrameSet
from services.recogniser.transcribe import strikes

GRID = np.round(np.arange(0.1, 0.91, 0.05), 2)
"""Thresholds tried."""
CHORD_OPTIONS = (0.0, 0.02, 0.03)
"""Chord windows tried, seconds."""
SNAP_OPTIONS = (0, 1, 2, 3)
"""Distances tried within which a class strike moves to an onset-output peak, frames (``FrameNet.snap_frames``)."""
HIHAT_SNARE_OPTIONS = (0.0, 0.5, 0.7, 1.0, 1.3)
"""Ratios tried for dropping a snare peak under a hi-hat peak (``FrameNet.hihat_snare``; 0: never)."""
MERGE_S = 0.02
"""Reference strikes closer than this are one onset (as the benchmark counts them), seconds."""


def merge(times: np.ndarray, gap: float) -> np.ndarray:
    """Sorted times with any time within ``gap`` of the previous kept one dropped."""
    out: list[float] = []
    for t in np.sort(times):
        if not out or t - out[-1] > gap:
            out.append(float(t))
    return np.asarray(out)


def pooled_f(pairs: list[tuple[np.ndarray, np.ndarray]], window: float = 0.05) -> float:
    """F-measure of (reference times, estimated times) pairs, matches and counts pooled."""
    matched = n = 0
    for ref, est in pairs:
        if len(ref) and len(est):
            matched += len(mir_eval.util.match_events(ref, est, window))
        n += len(ref) + len(est)
    return 2 * matched / max(1, n)


def outputs(net: FrameNet, val: FrameSet) -> list[np.ndarray]:
    """The network's framewise outputs for every validation excerpt."""
    return [net.forward(val.excerpt(e, net.inputs).astype(np.float32)) for e in range(val.n_excerpts)]


def _snare_f(net: FrameNet, val: FrameSet, outs: list[np.ndarray]) -> float:
    pairs = []
    for e, out in enumerate(outs):
        h = val.excerpt_hits(e)
        est = np.unique([ev.time for ev in strikes(net, out) if ev.cls == SNARE])
        pairs.append((np.unique(h[h[:, 2] == SNARE, 1]), est))
    return pooled_f(pairs)


def _onset_f(net: FrameNet, val: FrameSet, outs: list[np.ndarray]) -> float:
    pairs = []
    for e, out in enumerate(outs):
        est = np.unique([ev.time for ev in strikes(net, out)])
        pairs.append((merge(val.excerpt_hits(e)[:, 1], MERGE_S), est))
    return pooled_f(pairs)


def choose(net: FrameNet, val: FrameSet, outs: list[np.ndarray] | None = None, rules: bool = False) -> None:
    """Set ``net.thresholds`` and ``net.chord_s`` from the validation excerpts (printing the F-measures); with
    ``rules`` also ``net.snap_frames`` and ``net.hihat_snare`` (else both are off)."""
    outs = outs if outs is not None else outputs(net, val)
    refs = [val.excerpt_hits(e) for e in range(val.n_excerpts)]
    th = np.full(N_CLASSES + 1, 1.01, np.float32)
    for c in range(N_CLASSES):
        scores = []
        for g in GRID:
            pairs = [(np.unique(h[h[:, 2] == c, 1]), net.peaks(out[:, c], float(g)) / FPS + net.time_offset_s)
                     for h, out in zip(refs, outs, strict=True)]
            scores.append(pooled_f(pairs))
        th[c] = GRID[int(np.argmax(scores))]
        n = sum(int(np.sum(h[:, 2] == c)) for h in refs)
        print(f"  {CLASS_NAMES[c]:13s} validation-kit F {max(scores):.3f} at {th[c]:.2f} (n={n})", flush=True)
    net.thresholds = th
    net.hihat_snare = 0.0
    best = (-1.0, 1.01, net.chord_s, 0)
    for snap in SNAP_OPTIONS if rules else (0,):
        net.snap_frames = snap
        for chord in CHORD_OPTIONS:
            net.chord_s = chord
            for g in [*GRID, 1.01]:
                net.thresholds[N_CLASSES] = g
                f = _onset_f(net, val, outs)
                if f > best[0]:
                    best = (f, float(g), chord, snap)
    net.thresholds[N_CLASSES], net.chord_s, net.snap_frames = best[1], best[2], best[3]
    print(f"  {'onsets':13s} validation-kit F {best[0]:.3f} with onset threshold {best[1]:.2f}, "
          f"chord window {best[2] * 1000:.0f} ms" + (f", strikes moved to onset peaks within {best[3]} frames"
                                                     if rules else ""), flush=True)
    if not rules:
        return
    scores = []
    for r in HIHAT_SNARE_OPTIONS:
        net.hihat_snare = r
        scores.append(_snare_f(net, val, outs))
    net.hihat_snare = HIHAT_SNARE_OPTIONS[int(np.argmax(scores))]
    print(f"  {'snare':13s} validation-kit F {max(scores):.3f} ({scores[0]:.3f} before) dropping snare peaks under "
          f"hi-hat peaks at ratio {net.hihat_snare:.1f}", flush=True)

