"""Fit the recogniser's live classifier (a per-candidate MLP) on Groove performances rendered with the training kits.

Usage::

    nice -n 15 python -m services.recogniser.training.train [--excerpts 1000] [--val-excerpts 150] [--workers 2]

Writes ``--out`` with this live classifier and the offline network of ``--offline-from``
(:mod:`.train_net` trains that one).
Needs scikit-learn (``pip install -e '.[train]'``), mir_eval and Debian's ``hydrogen-drumkits``
(``apt-get install hydrogen-drumkits``).
Audio is rendered in memory: the MLP is fitted on ``TRAIN_KITS`` plus Batteur's own
modal and signal synthesis (:mod:`~services.recogniser.training.modal`; ``--no-synth`` leaves
them out), half the excerpts on kits mixed from several; the decision thresholds are chosen
on excerpts rendered with ``VALID_KITS`` (a validation kit, never fitted on), and
``TEST_KITS`` are kept for the benchmark. Features are cached in ``--cache`` (default: a temp dir).
Deterministic for a given ``--seed``. About 13 minutes on a shared 2-core machine.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import sys
import time
import zipfile
from collections.abc import Callable
from contextlib import nullcontext
from pathlib import Path

import numpy as np

from common.exit_status import FAILED, INTERRUPTED
from services.recogniser.audio import SAMPLE_RATE, resample
from services.recogniser.classes import CLASS_NAMES, N_CLASSES
from services.recogniser.model import Classifier, Model, load_model
from services.recogniser.training.dataset import (
    CANDIDATE_DELTA,
    FIELDS,
    LIVE_OFFSETS,
    Examples,
    concat,
    label,
)
from services.recogniser.training.excerpts import (
    DRY_P,
    FIT_KITS,
    VALID_DRY_P,
    Job,
    add_arguments,
    check_files,
    jobs,
    kits_installed,
    prepare,
    render_excerpt,
)
from services.recogniser.training.frames import ONSET_MERGE_S, Progress, onset_times
from services.recogniser.training.kits import RENDER_RATE, TRAIN_KITS, VALID_KITS
from services.recogniser.training.options import import_or_say, prog_of, save_or_say
from services.recogniser.transcribe import SUPPRESS_S, DrumEvent, group_chords

PROG = prog_of("services.recogniser.training.train")
"""The command's name in its usage and error lines."""
NEEDS = ("mir_eval", "sklearn.linear_model", "sklearn.neural_network")
"""Training-only dependencies, imported once the command line is checked: ``--help`` and the option checks do
without them."""
CACHE_TAG = "v8"
"""Changes when the rendering or features change, so stale cached examples are not reused."""
HIDDEN_LIVE = (64, 32)
"""Hidden layer widths of the live MLP (kept small: it runs once per candidate in real time)."""
MAX_WEIGHT = 4.0
"""Cap of the class-balancing weight of a candidate with a hit of a rare class."""


def _excerpt(job: Job) -> Examples:
    audio, hits = render_excerpt(job)  # the live classifier reads 22,050 Hz
    return label(resample(audio, RENDER_RATE, SAMPLE_RATE), hits)


def make_examples(n: int, seed: int, workers: int, kits: tuple[str, ...], dry_p: float = DRY_P) -> Examples:
    """Render ``n`` excerpts of Groove train-split performances with ``kits`` (a share ``dry_p`` of them
    dry, the others with room, EQ and noise) and label their candidates."""
    prepare(kits)
    todo = jobs(n, seed, kits, dry_p)
    parts = []
    print(f"rendering {n} excerpts ...", flush=True)
    progress = Progress(n)
    with mp.Pool(workers) if workers > 1 else nullcontext() as pool:
        results = pool.imap(_excerpt, todo, chunksize=4) if pool is not None else map(_excerpt, todo)
        for e, part in enumerate(results):  # imap, not map: progress lines while a long render runs
            parts.append(part)
            progress.done(e + 1)
    return concat(parts)


def class_weights(y: np.ndarray) -> np.ndarray:
    """Per-row fitting weight: rows with a hit of a rare class weigh (n_most_common / n_class) ** 0.5,
    capped at :data:`MAX_WEIGHT`; rows without a hit weigh 1."""
    n = np.maximum(y.sum(axis=0), 1.0)
    per_class = np.minimum((n.max() / n) ** 0.5, MAX_WEIGHT)
    return np.maximum(1.0, (y * per_class).max(axis=1)).astype(np.float64)


def fit_variant(x: np.ndarray, ex: Examples, x_val: np.ndarray, val: Examples, offsets: tuple[int, ...],
                hidden: tuple[int, ...], seed: int, negatives: float = 0.4, epochs: int = 30) -> Classifier:
    """Fit one MLP variant with a class output per class plus an onset output (any class struck).

    ``negatives``: fraction of the no-hit candidates used for fitting. Thresholds are chosen
    on ``x_val``/``val``, candidates of excerpts rendered with the validation kits only.
    """
    from sklearn.linear_model import Ridge
    from sklearn.neural_network import MLPClassifier

    mean = x.mean(axis=0)
    scale = x.std(axis=0) + 1e-3
    z = ((x - mean) / scale).astype(np.float32)
    rng = np.random.default_rng(seed)
    y = np.concatenate([ex.y, (ex.y.sum(axis=1, keepdims=True) > 0)], axis=1).astype(int)
    fit_rows = (ex.y.sum(axis=1) > 0) | (rng.random(len(x)) < negatives)
    mlp = MLPClassifier(hidden_layer_sizes=hidden, alpha=1e-3, batch_size=512, learning_rate_init=2e-3,
                        max_iter=epochs, early_stopping=True, n_iter_no_change=4, random_state=seed, verbose=True)
    mlp.fit(z[fit_rows], y[fit_rows], sample_weight=class_weights(ex.y[fit_rows]))
    prob = mlp.predict_proba(((x_val - mean) / scale).astype(np.float32))
    thresholds = choose_thresholds(prob, val)
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


def _events(val: Examples, hit: np.ndarray, prob: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per validation excerpt: (times s, classes) of the strikes decided, after per-class suppression and
    grouping into chords (as :func:`~services.recogniser.transcribe.transcribe` does)."""
    out = []
    for e in range(int(val.excerpt.max()) + 1 if len(val.excerpt) else 0):
        rows = np.flatnonzero(val.excerpt == e)
        times: list[float] = []
        classes: list[int] = []
        for c in range(N_CLASSES):
            sel = rows[hit[rows, c]]
            kept: list[float] = []
            for i in sel[np.argsort(-prob[sel, c], kind="stable")]:
                if all(abs(val.time[i] - t) >= SUPPRESS_S for t in kept):
                    kept.append(float(val.time[i]))
            times += kept
            classes += [c] * len(kept)
        order = np.argsort(times, kind="stable")
        grouped = group_chords([DrumEvent(times[i], classes[i], 64, 1.0) for i in order])
        out.append((np.array([g.time for g in grouped]), np.array([g.cls for g in grouped], int)))
    return out


def event_f(val: Examples, found: list[tuple[np.ndarray, np.ndarray]], classes: tuple[int, ...] | None,
            window: float = 0.05) -> float:
    """F-measure pooled over the validation excerpts for strikes of ``classes`` (None: class-agnostic onsets,
    reference strikes closer than 20 ms being one onset), ``window`` seconds tolerance."""
    import mir_eval

    matched = n_ref = n_est = 0
    for e, (times, cls) in enumerate(found):
        h = val.hits[val.hits[:, 0] == e]
        if classes is None:
            ref = onset_times(h[:, 1], ONSET_MERGE_S)
            est = onset_times(times, 1e-4)
        else:
            ref = np.unique(h[np.isin(h[:, 2], classes), 1])
            est = np.unique(times[np.isin(cls, classes)])
        if len(ref) and len(est):
            matched += len(mir_eval.util.match_events(ref, est, window))
        n_ref += len(ref)
        n_est += len(est)
    return 2 * matched / max(1, n_ref + n_est)


def choose_thresholds(prob: np.ndarray, val: Examples) -> np.ndarray:
    """Decision thresholds (one per class, then the onset output's) maximising strike-level F-measure
    (50 ms) on the validation kit's excerpts: each class's on its own, then the onset output's on the
    class-agnostic onsets with the class thresholds fixed."""
    n_out = prob.shape[1]
    thresholds = np.full(n_out, 0.5, np.float32)
    if n_out > N_CLASSES:
        thresholds[N_CLASSES] = 1.01  # onset output off while the classes are tuned
    grid = np.linspace(0.05, 0.9, 18)
    for c in range(N_CLASSES):
        scores = []
        for th in grid:
            hit = np.zeros((len(prob), N_CLASSES), bool)
            hit[:, c] = prob[:, c] >= th
            scores.append(event_f(val, _events(val, hit, prob), (c,)))
        thresholds[c] = grid[int(np.argmax(scores))]
        n = int(np.sum(val.hits[:, 2] == c))
        print(f"  {CLASS_NAMES[c]:13s} validation-kit F {max(scores):.3f} at {thresholds[c]:.2f} (n={n})", flush=True)
    if n_out > N_CLASSES:
        scores = []
        options = [*grid, 1.01]
        for th in options:
            thresholds[N_CLASSES] = th
            scores.append(event_f(val, _events(val, _decide(prob, thresholds), prob), None))
        thresholds[N_CLASSES] = options[int(np.argmax(scores))]
        print(f"  {'onsets':13s} validation-kit F {max(scores):.3f} with onset threshold "
              f"{thresholds[N_CLASSES]:.2f} (off: {scores[-1]:.3f})", flush=True)
    return thresholds


def _decide(prob: np.ndarray, thresholds: np.ndarray) -> np.ndarray:
    c = Classifier(offsets=(0,), delta=0.0, time_offset_s=0.0, mean=np.zeros(1), scale=np.ones(1),
                   weights=[np.zeros((1, N_CLASSES + 1))], biases=[np.zeros(N_CLASSES + 1)],
                   thresholds=thresholds, vel_w=np.zeros((2, N_CLASSES)))
    return c.decide(prob)


def _examples(cache: Path, n: int, seed: int, workers: int, kits: tuple[str, ...], dry_p: float = DRY_P) -> Examples:
    if cache.exists():
        try:
            with np.load(cache) as z:
                d = {k: z[k] for k in FIELDS}
            return Examples(d["x_live"], d["y"], d["velocity"], d["dt"], int(d["missed"]), d["time"],
                            d["excerpt"], d["hits"])
        except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:  # cut short: render again
            print(f"the cached {cache} cannot be read ({exc}): rendering it again", flush=True)
    ex = make_examples(n, seed, workers, kits, dry_p)
    part = cache.with_name(f".{cache.name}.part.npz")  # renamed when whole: a Ctrl-C leaves no broken cache
    np.savez(part, **{k: getattr(ex, k) for k in FIELDS})
    part.replace(cache)
    return ex


def retune(path: Path, val: Examples, out: Path) -> int:
    """Choose the thresholds of a fitted model again on the validation examples and write it to ``out``."""
    model = load_model(path)
    model.live.thresholds = choose_thresholds(model.live.probabilities(val.x_live), val)
    model.meta["live_retuned"] = True
    if save_or_say(model, out, PROG) is None:
        return FAILED
    print(f"wrote {out}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """Fit the live classifier; the exit status (README, "Exit status": 2 a bad option value, 1 a file it cannot
    use or data not installed, 130 Ctrl-C)."""
    ap = argparse.ArgumentParser(prog=PROG, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_arguments(ap, excerpts=1000, keeps="offline")
    ap.add_argument("--no-synth", dest="synth", action="store_false",
                    help="fit on the Hydrogen kits only (default: also Batteur's own modal and signal synthesis)")
    args = ap.parse_args(argv)
    if not import_or_say(NEEDS, PROG):  # scikit-learn or mir_eval not installed: said what to install
        return FAILED
    models: list[tuple[str, Path, Callable[[Path], object]]] = [("--offline-from", args.offline_from, load_model)]
    models += [("--retune", args.retune, load_model)] if args.retune is not None else []
    if not check_files(args, models, PROG) or not kits_installed(PROG):
        return FAILED
    try:
        return run(args)
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted: nothing written to {args.out}", file=sys.stderr)
        return INTERRUPTED


def run(args: argparse.Namespace) -> int:
    """Render, fit, tune and write what the checked command line ``args`` asks for."""
    t0 = time.time()
    val = _examples(args.cache / f"{CACHE_TAG}-val-{args.val_excerpts}-{args.seed}.npz", args.val_excerpts,
                    args.seed + 1000, args.workers, VALID_KITS, VALID_DRY_P)
    if args.retune is not None:
        return retune(args.retune, val, args.out)
    kits = FIT_KITS if args.synth else TRAIN_KITS
    tag = CACHE_TAG + ("s" if args.synth else "")
    ex = _examples(args.cache / f"{tag}-train-{args.excerpts}-{args.seed}.npz", args.excerpts, args.seed,
                   args.workers, kits)
    for name, e in (("training", ex), ("validation-kit", val)):
        n_hits = int(e.y.sum()) + e.missed
        print(f"{name}: {len(e.y)} candidate onsets, {int((e.y.sum(1) > 0).sum())} with a hit; "
              f"{e.missed}/{n_hits} hits without a candidate; {time.time() - t0:.0f} s")
    print("live classifier:")
    live = fit_variant(ex.x_live, ex, val.x_live, val, LIVE_OFFSETS, HIDDEN_LIVE, args.seed)
    base = load_model(args.offline_from)
    meta = dict(base.meta, live_trained_on=list(kits), live_thresholds_from=list(VALID_KITS),
                live_excerpts=args.excerpts, live_seed=args.seed)
    size = save_or_say(Model(offline=base.offline, live=live, meta=meta), args.out, PROG)
    if size is None:  # e.g. a disk full by the end of the run
        return FAILED
    print(f"wrote {args.out} ({size / 1024:.0f} KiB) in {time.time() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
