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
from services.recogniser.framenet import SNARE, FrameNet
from services.recogniser.training.frames import ONSET_MERGE_S, FrameSet, onset_times
from services.recogniser.transcribe import strikes

GRID = np.round(np.arange(0.1, 0.91, 0.05), 2)
"""Thresholds tried."""
CHORD_OPTIONS = (0.0, 0.01, 0.02, 0.03)
"""Chord windows tried, seconds."""
SNAP_OPTIONS_S = (0.0, 0.01, 0.02, 0.03)
"""Distances tried within which a class strike moves to an onset-output peak, seconds (``FrameNet.snap_frames``,
in frames: 0-3 frames of 10 ms, 0-6 of 5 ms)."""
PEAK_MAX_S = 0.01
"""Peak windows tried: a strike is the maximum of +-1 .. this many seconds of frames (``FrameNet.peak_frames``;
10 ms frames: 1 only; 5 ms frames: 1 or 2)."""
HIHAT_SNARE_OPTIONS = (0.0, 0.5, 0.7, 1.0, 1.3)
"""Ratios tried for dropping a snare peak under a hi-hat peak (``FrameNet.hihat_snare``; 0: never)."""


def pooled_counts(pairs: list[tuple[np.ndarray, np.ndarray]], window: float = 0.05) -> tuple[int, int]:
    """(matches, references + estimates) of (reference times, estimated times) pairs, summed over the pairs."""
    matched = n = 0
    for ref, est in pairs:
        if len(ref) and len(est):
            matched += len(mir_eval.util.match_events(ref, est, window))
        n += len(ref) + len(est)
    return matched, n


def f_measure(matched: int, n: int) -> float:
    """F-measure from the matches and the count of references plus estimates (0 when both are none)."""
    return 2 * matched / max(1, n)


def pooled_f(pairs: list[tuple[np.ndarray, np.ndarray]], window: float = 0.05) -> float:
    """F-measure of (reference times, estimated times) pairs, matches and counts pooled."""
    return f_measure(*pooled_counts(pairs, window))


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
        pairs.append((onset_times(val.excerpt_hits(e)[:, 1], ONSET_MERGE_S), est))
    return pooled_f(pairs)


def _class_thresholds(net: FrameNet, refs: list[np.ndarray], outs: list[np.ndarray]
                      ) -> tuple[np.ndarray, list[float], float]:
    """Each class's best threshold on its own strikes with the net's ``peak_frames``: (thresholds, each
    class's F-measure, the F-measure of all classes' strikes pooled)."""
    th = np.full(N_CLASSES + 1, 1.01, np.float32)
    best_f, matched, total = [], 0, 0
    for c in range(N_CLASSES):
        counts = []
        for g in GRID:
            pairs = [(np.unique(h[h[:, 2] == c, 1]), net.peaks(out[:, c], float(g)) / net.fps + net.time_offset_s)
                     for h, out in zip(refs, outs, strict=True)]
            counts.append(pooled_counts(pairs))
        scores = [f_measure(m, n) for m, n in counts]
        k = int(np.argmax(scores))
        th[c] = GRID[k]
        best_f.append(scores[k])
        matched += counts[k][0]
        total += counts[k][1]
    return th, best_f, f_measure(matched, total)


def choose(net: FrameNet, val: FrameSet, outs: list[np.ndarray] | None = None, rules: bool = False) -> None:
    """Set ``net.thresholds`` and ``net.chord_s`` from the validation excerpts (printing the F-measures); with
    ``rules`` also ``net.snap_frames`` and ``net.hihat_snare``, else the net keeps its own (a new network's are
    off; a model retuned keeps the rules it was shipped with). With frames finer than
    :data:`PEAK_MAX_S` (or a net whose ``peak_frames`` is above 1), also ``net.peak_frames``: from 1 to the
    larger of the two, the best F-measure of all classes' strikes pooled."""
    outs = outs if outs is not None else outputs(net, val)
    refs = [val.excerpt_hits(e) for e in range(val.n_excerpts)]
    peak_options = range(1, max(net.peak_frames, round(PEAK_MAX_S * net.fps)) + 1)
    tried = []
    for w in peak_options:
        net.peak_frames = w
        tried.append((*_class_thresholds(net, refs, outs), w))
    th, class_f, _, net.peak_frames = max(tried, key=lambda r: r[2])
    for c in range(N_CLASSES):
        n = sum(int(np.sum(h[:, 2] == c)) for h in refs)
        print(f"  {CLASS_NAMES[c]:13s} validation-kit F {class_f[c]:.3f} at {th[c]:.2f} (n={n})", flush=True)
    if len(tried) > 1:
        print(f"  strikes are maxima over +-{net.peak_frames} frames (class strikes, F pooled: "
              + ", ".join(f"+-{w}: {f:.4f}" for *_, f, w in tried) + ")", flush=True)
    net.thresholds = th
    if rules:
        net.hihat_snare = 0.0  # chosen last, on the snare alone
    best = (-1.0, 1.01, net.chord_s, net.snap_frames)
    snaps = sorted({round(s * net.fps) for s in SNAP_OPTIONS_S})
    for snap in snaps if rules else [net.snap_frames]:
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
          f"chord window {best[2] * 1000:.0f} ms, strikes moved to onset peaks within {best[3]} frames", flush=True)
    if not rules:
        return
    scores = []
    for r in HIHAT_SNARE_OPTIONS:
        net.hihat_snare = r
        scores.append(_snare_f(net, val, outs))
    net.hihat_snare = HIHAT_SNARE_OPTIONS[int(np.argmax(scores))]
    print(f"  {'snare':13s} validation-kit F {max(scores):.3f} ({scores[0]:.3f} before) dropping snare peaks under "
          f"hi-hat peaks at ratio {net.hihat_snare:.1f}", flush=True)


if __name__ == "__main__":  # run as a program by mistake: say which commands train
    from services.recogniser.training.options import not_a_command

    not_a_command(__spec__.name)
