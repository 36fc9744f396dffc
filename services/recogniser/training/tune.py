"""Choosing the offline network's decision thresholds on the validation kit (never on the held-out kit).

Each choice maximises the strike-level F-measure at 50 ms (mir_eval's onset matching,
pooled over the validation excerpts), the benchmark's measure: first every class's
threshold on its own strikes, then the onset output's threshold and the chord window
on the class-agnostic onsets.
"""

from __future__ import annotations

import mir_eval
import numpy as np

from services.recogniser.classes import CLASS_NAMES, N_CLASSES
from services.recogniser.features import FPS
from services.recogniser.framenet import FrameNet
from services.recogniser.training.frames import FrameSet
from services.recogniser.transcribe import strikes

GRID = np.round(np.arange(0.1, 0.91, 0.05), 2)
"""Thresholds tried."""
CHORD_OPTIONS = (0.0, 0.02, 0.03)
"""Chord windows tried, seconds."""
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


def _onset_f(net: FrameNet, val: FrameSet, outs: list[np.ndarray]) -> float:
    pairs = []
    for e, out in enumerate(outs):
        est = np.unique([ev.time for ev in strikes(net, out)])
        pairs.append((merge(val.excerpt_hits(e)[:, 1], MERGE_S), est))
    return pooled_f(pairs)


def choose(net: FrameNet, val: FrameSet, outs: list[np.ndarray] | None = None) -> None:
    """Set ``net.thresholds`` and ``net.chord_s`` from the validation excerpts (printing the F-measures)."""
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
    best = (-1.0, 1.01, net.chord_s)
    for chord in CHORD_OPTIONS:
        net.chord_s = chord
        for g in [*GRID, 1.01]:
            net.thresholds[N_CLASSES] = g
            f = _onset_f(net, val, outs)
            if f > best[0]:
                best = (f, float(g), chord)
    net.thresholds[N_CLASSES], net.chord_s = best[1], best[2]
    print(f"  {'onsets':13s} validation-kit F {best[0]:.3f} with onset threshold {best[1]:.2f}, "
          f"chord window {best[2] * 1000:.0f} ms", flush=True)

