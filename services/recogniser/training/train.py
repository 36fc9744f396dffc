"""Fit the recogniser's model on Groove MIDI performances rendered with the training kits.

Usage::

    python -m services.recogniser.training.train [--excerpts 800] [--out services/recogniser/models/recogniser.npz]

Needs scikit-learn and Debian's ``hydrogen-drumkits`` (``apt-get install hydrogen-drumkits``).
Audio is rendered in memory (kits in ``TRAIN_KITS`` only; ``TEST_KITS`` are kept
for the benchmark); features are cached in ``--cache`` (default: a temp dir).
Deterministic for a given ``--seed``.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import tempfile
import time
from pathlib import Path

import numpy as np
from sklearn.linear_model import Ridge
from sklearn.neural_network import MLPClassifier

from services.recogniser.classes import CLASS_NAMES, N_CLASSES
from services.recogniser.model import MODEL_PATH, Classifier, Model
from services.recogniser.training.dataset import (
    CANDIDATE_DELTA,
    LIVE_OFFSETS,
    OFFLINE_OFFSETS,
    Examples,
    concat,
    groove_files,
    label,
)
from services.recogniser.training.kits import TRAIN_KITS, load_kit
from services.recogniser.training.render import augment, read_notes, render

EXCERPT_S = 30.0

_KITS: dict = {}


def _excerpt(job: tuple[int, str, float, int]) -> Examples:
    seed, path, duration, _ = job
    rng = np.random.default_rng(seed)
    name = TRAIN_KITS[int(rng.integers(len(TRAIN_KITS)))]
    if name not in _KITS:
        _KITS[name] = load_kit(name)
    start = float(rng.uniform(0, max(0.0, duration - EXCERPT_S)))
    notes = [n for n in read_notes(path) if start <= n.time < start + EXCERPT_S]
    from services.recogniser.training.render import Note

    notes = [Note(n.time - start + 0.2, n.pitch, n.velocity) for n in notes]
    audio, hits = render(notes, _KITS[name], rng, duration=EXCERPT_S + 0.2, vary=rng.random() < 0.7)
    return label(augment(audio, rng), hits)


def make_examples(n: int, seed: int, workers: int) -> Examples:
    files = [f for f in groove_files("train") if f[1] >= 20.0]  # long performances (beats with fills)
    rng = np.random.default_rng(seed)
    picks = rng.choice(len(files), size=n, replace=n > len(files))
    jobs = [(seed * 100_000 + i, str(files[k][0]), files[k][1], i) for i, k in enumerate(picks)]
    with mp.Pool(workers) as pool:
        parts = pool.map(_excerpt, jobs, chunksize=4)
    return concat(parts)


def fit_variant(x: np.ndarray, ex: Examples, val: np.ndarray, offsets: tuple[int, ...], hidden: tuple[int, ...],
                seed: int, negatives: float = 0.4, epochs: int = 25) -> Classifier:
    """Fit one MLP variant; ``negatives``: fraction of the no-hit candidates used for fitting (all are used
    to choose the thresholds on the ``val`` rows)."""
    mean = x[~val].mean(axis=0)
    scale = x[~val].std(axis=0) + 1e-3
    z = ((x - mean) / scale).astype(np.float32)
    rng = np.random.default_rng(seed)
    fit_rows = ~val & ((ex.y.sum(axis=1) > 0) | (rng.random(len(x)) < negatives))
    mlp = MLPClassifier(hidden_layer_sizes=hidden, alpha=1e-3, batch_size=512, learning_rate_init=2e-3,
                        max_iter=epochs, early_stopping=True, n_iter_no_change=4, random_state=seed, verbose=True)
    mlp.fit(z[fit_rows], ex.y[fit_rows].astype(int))
    prob = mlp.predict_proba(z[val])
    thresholds = np.zeros(N_CLASSES, np.float32)
    for c in range(N_CLASSES):  # threshold maximising F1 on the held-out excerpts
        yt = ex.y[val, c] > 0
        best = (0.0, 0.5)
        for th in np.linspace(0.1, 0.9, 33):
            yp = prob[:, c] >= th
            tp = np.sum(yp & yt)
            f = 2 * tp / max(1, np.sum(yp) + np.sum(yt))
            if f > best[0]:
                best = (f, th)
        thresholds[c] = best[1]
        print(f"  {CLASS_NAMES[c]:13s} val F1 {best[0]:.3f} at {best[1]:.2f} (n={int(yt.sum())})")
    vel_w = np.zeros((x.shape[1] + 1, N_CLASSES), np.float32)
    for c in range(N_CLASSES):
        pos = ex.y[:, c] > 0
        if pos.sum() > 10:
            r = Ridge(alpha=10.0).fit(z[pos], ex.velocity[pos, c] / 127.0)
            vel_w[:-1, c] = r.coef_
            vel_w[-1, c] = r.intercept_
    dt = ex.dt[~np.isnan(ex.dt)]
    return Classifier(
        offsets=offsets, delta=CANDIDATE_DELTA, time_offset_s=float(np.median(dt)) if dt.size else 0.0,
        mean=mean.astype(np.float32), scale=scale.astype(np.float32),
        weights=[w.astype(np.float32) for w in mlp.coefs_], biases=[b.astype(np.float32) for b in mlp.intercepts_],
        thresholds=thresholds, vel_w=vel_w,
    )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--excerpts", type=int, default=800, help="30-second excerpts to render (default 800)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--cache", type=Path, default=Path(tempfile.gettempdir()) / "batteur-recogniser-cache")
    ap.add_argument("--out", type=Path, default=MODEL_PATH)
    args = ap.parse_args(argv)
    args.cache.mkdir(parents=True, exist_ok=True)
    cache = args.cache / f"examples-{args.excerpts}-{args.seed}.npz"
    t0 = time.time()
    if cache.exists():
        with np.load(cache) as z:
            ex = Examples(z["x_offline"], z["x_live"], z["y"], z["velocity"], z["dt"], int(z["missed"]))
    else:
        ex = make_examples(args.excerpts, args.seed, args.workers)
        np.savez(cache, x_offline=ex.x_offline, x_live=ex.x_live, y=ex.y, velocity=ex.velocity, dt=ex.dt,
                 missed=ex.missed)
    n_hits = int(ex.y.sum()) + ex.missed
    print(f"{len(ex.y)} candidate onsets, {int((ex.y.sum(1) > 0).sum())} with a hit; "
          f"{ex.missed}/{n_hits} hits without a candidate; {time.time() - t0:.0f} s")
    rng = np.random.default_rng(args.seed)
    val = rng.random(len(ex.y)) < 0.1
    print("offline variant:")
    offline = fit_variant(ex.x_offline, ex, val, OFFLINE_OFFSETS, (128, 64), args.seed)
    print("live variant:")
    live = fit_variant(ex.x_live, ex, val, LIVE_OFFSETS, (64, 32), args.seed)
    meta = {"trained_on": list(TRAIN_KITS), "excerpts": args.excerpts, "seed": args.seed,
            "data": "Groove MIDI Dataset train split (CC BY 4.0) rendered with hydrogen-drumkits"}
    Model(offline=offline, live=live, meta=meta).save(args.out)
    print(f"wrote {args.out} ({args.out.stat().st_size / 1024:.0f} KiB) in {time.time() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
