"""Benchmark the percussion recogniser on Groove validation performances rendered with an unseen kit.

Prints per-class F-measure (precision, recall) at 50 ms and 30 ms tolerance
(mir_eval's onset matching, pooled over all files), the class-agnostic onset
F-measure, and the transcription speed as a multiple of real time.

Goals (issue 10): onsets F >= 0.93; kick, snare, hi-hat each F >= 0.85; speed >= 50x.
The hi-hat row pools closed and open hi-hat (the open/closed split is shown too).

Needs Debian's hydrogen-drumkits (the kit; exits 1 with an install hint without it) and mir_eval. Usage::

    python bench/recogniser_bench.py          # the whole validation split, whole performances (about 3 min)
    python bench/recogniser_bench.py --files 30 --seconds 60 [--augment] [--live]   # a quicker sample
    python bench/recogniser_bench.py --kit Millo_MultiLayered2 --split train --files 60 --seconds 60   # to tune on
    python bench/recogniser_bench.py --model new.npz services/recogniser/models/recogniser.npz  # same renders

Several ``--model`` files are scored on the same renders, each file transcribed by each model in turn
(so their speeds are measured under the same load).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import mir_eval  # noqa: E402

from common.messages.recogniser import DrumHit  # noqa: E402
from services.recogniser.audio import SAMPLE_RATE, resample  # noqa: E402
from services.recogniser.classes import CLASS_NAMES, class_of_note  # noqa: E402
from services.recogniser.core import LiveRecogniser  # noqa: E402
from services.recogniser.model import MODEL_PATH, Model, load_model  # noqa: E402
from services.recogniser.training.dataset import groove_files  # noqa: E402
from services.recogniser.training.kits import (  # noqa: E402
    RENDER_RATE,
    TEST_KITS,
    TRAIN_KITS,
    VALID_KITS,
    KitsMissingError,
    load_kit,
    require_kits,
)
from services.recogniser.training.render import Hit, Note, augment, normalise, read_notes, render  # noqa: E402
from services.recogniser.transcribe import PEAK, transcribe  # noqa: E402

GROUPS: dict[str, tuple[int, ...]] = {name: (i,) for i, name in enumerate(CLASS_NAMES)}
GROUPS["hihat (open+closed)"] = (2, 3)
GROUPS["toms (all)"] = (4, 5, 6)
MERGE_S = 0.02
"""Reference onsets closer than this are one onset for the class-agnostic score, seconds."""


def merge(times: np.ndarray, gap: float = MERGE_S) -> np.ndarray:
    out: list[float] = []
    for t in np.sort(times):
        if not out or t - out[-1] > gap:
            out.append(float(t))
    return np.asarray(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--files", type=int, default=None,
                    help="performances drawn at random from the split (default: all of them)")
    ap.add_argument("--seconds", type=float, default=None,
                    help="at most this much of each, seconds (default: the whole performance)")
    ap.add_argument("--kit", default=TEST_KITS[0], help="hydrogen kit to render with (default: the held-out one)")
    ap.add_argument("--split", default="validation", choices=("validation", "train", "test"),
                    help="Groove split to render (default validation; use train with --kit of VALID_KITS to tune)")
    ap.add_argument("--augment", action="store_true", help="add room, EQ and noise as in training")
    ap.add_argument("--model", type=Path, nargs="+", default=[MODEL_PATH],
                    help="model file(s) to score; several are scored on the same renders (default: the shipped one)")
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--live", action="store_true", help="also score the live core (fed 128-sample blocks)")
    args = ap.parse_args(argv)
    if (args.files is not None and args.files < 1) or (args.seconds is not None and args.seconds <= 0):
        ap.error("--files must be at least 1 and --seconds above 0")
    try:
        require_kits([args.kit])
    except KitsMissingError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1

    models = [load_model(p) for p in args.model]
    for path, model in zip(args.model, models, strict=True):
        if args.kit in set(model.meta.get("trained_on", TRAIN_KITS)):
            print(f"warning: {args.kit} was used for training {path}", file=sys.stderr)
    kit = load_kit(args.kit)
    rng = np.random.default_rng(args.seed)
    files = groove_files(args.split)
    wanted = len(files) if args.files is None else min(args.files, len(files))
    picks = rng.choice(len(files), size=wanted, replace=False)
    longest = np.inf if args.seconds is None else args.seconds
    runs: list[dict[str, list[tuple[list[Hit], list[tuple[float, int]]]]]] = [
        {"offline": [], "live": []} for _ in models]
    latencies: list[list[float]] = [[] for _ in models]
    compute_s = [0.0 for _ in models]
    audio_s = 0.0
    warm = (0.01 * np.random.default_rng(0).standard_normal(RENDER_RATE)).astype(np.float32)
    for model in models:  # first calls (filterbanks, FFT set-up) are not timed
        transcribe(warm, model, sample_rate=RENDER_RATE)
    for done, k in enumerate(picks, 1):
        print(f"\r  rendering and transcribing {done}/{len(picks)}", end="", file=sys.stderr, flush=True)
        path, _ = files[int(k)]
        notes = [Note(n.time + 0.1, n.pitch, n.velocity) for n in read_notes(path) if n.time < longest]
        if not notes:
            continue
        audio, hits = render(notes, kit, rng, duration=min(longest, notes[-1].time + 1.5))
        audio = augment(audio, rng) if args.augment else normalise(audio)
        audio_s += len(audio) / RENDER_RATE
        live_audio = resample(audio, RENDER_RATE, SAMPLE_RATE) if args.live else audio  # the live path's rate
        for i, model in enumerate(models):
            t0 = time.perf_counter()  # a network of another rate than the render's: its resampling is timed too
            events = transcribe(audio, model, sample_rate=RENDER_RATE)
            compute_s[i] += time.perf_counter() - t0
            runs[i]["offline"].append((hits, [(e.time, e.cls) for e in events]))
            if args.live:
                runs[i]["live"].append((hits, live_hits(model, live_audio, latencies[i])))

    print(file=sys.stderr)
    print(f"kit: {args.kit}; {len(picks)} Groove {args.split} files, "
          f"{audio_s:.0f} s of audio; {'augmented' if args.augment else 'dry'} render")
    for i, (path, model) in enumerate(zip(args.model, models, strict=True)):
        seen = ("used for training" if args.kit in set(model.meta.get("trained_on", TRAIN_KITS))
                else "validation kit: thresholds chosen on it"
                if args.kit in model.meta.get("thresholds_from", VALID_KITS) else "never seen in training")
        net = model.offline
        print(f"\n=== model: {path} ({len(net.networks)} network{'s' if len(net.networks) > 1 else ''}, input "
              f"windows {', '.join(str(w) for w in net.inputs)} samples; kit {seen})")
        for name, files_run in runs[i].items():
            if files_run:
                what = "model.live, per-candidate MLP" if name == "live" else "model.offline, framewise network"
                print(f"\n{name} ({what}):")
                table(files_run)
                soft_recall(files_run)
        print(f"\nspeed (offline): {audio_s / max(compute_s[i], 1e-9):.0f}x real time "
              f"({compute_s[i]:.2f} s for {audio_s:.0f} s of audio)")
        if latencies[i]:
            lat = np.asarray(latencies[i]) * 1000
            print(f"live: audio needed after an onset before its hit is out (128-sample blocks): median "
                  f"{np.median(lat):.1f} ms, 95th percentile {np.percentile(lat, 95):.1f} ms, max {lat.max():.1f} ms")
    return 0


def live_hits(model: Model, audio: np.ndarray, latencies: list[float]) -> list[tuple[float, int]]:
    """The live core's strikes (time s, class) for ``audio`` (at :data:`SAMPLE_RATE`, the live path's rate) fed
    in 128-sample blocks; appends to ``latencies``
    the audio it needed after each onset before sending its hit, seconds."""
    core = LiveRecogniser(model, gain=PEAK / float(np.max(np.abs(audio))))
    found: list[tuple[float, int]] = []
    fed = 0
    for start in range(0, len(audio) + 128, 128):
        block = audio[start : start + 128]
        fed += len(block)
        for o in core.feed(block) if len(block) else core.flush():
            hit = o.message
            assert isinstance(hit, DrumHit)
            c = class_of_note(hit.note)
            if c is not None:
                found.append((hit.time, c))
            if len(block):
                latencies.append(fed / SAMPLE_RATE - hit.time)
    return found


VELOCITY_EDGES = (0, 20, 30, 40, 60, 128)
"""MIDI velocity bins of the onset recall table."""


def soft_recall(files_run: list[tuple[list[Hit], list[tuple[float, int]]]], window: float = 0.05) -> None:
    """Print the class-agnostic onset recall by the loudest MIDI velocity of the onset's strikes."""
    found = np.zeros(len(VELOCITY_EDGES) - 1)
    total = np.zeros(len(VELOCITY_EDGES) - 1)
    for hits, est in files_run:
        order = sorted(hits, key=lambda h: h.time)
        onsets: list[list[float]] = []  # [time, loudest velocity]
        for h in order:
            if onsets and h.time - onsets[-1][0] <= MERGE_S:
                onsets[-1][1] = max(onsets[-1][1], h.velocity)
            else:
                onsets.append([h.time, h.velocity])
        ref = np.array([o[0] for o in onsets])
        vel = np.array([o[1] for o in onsets])
        e = merge(np.array([t for t, _ in est]), 1e-4)
        hit = np.zeros(len(ref), bool)
        if len(ref) and len(e):
            hit[[i for i, _ in mir_eval.util.match_events(ref, e, window)]] = True
        b = np.digitize(vel, VELOCITY_EDGES) - 1
        np.add.at(total, b, 1)
        np.add.at(found, b, hit)
    cells = [f"{lo}-{hi - 1}: {f / t:.2f} ({t / total.sum():.0%})" if t else f"{lo}-{hi - 1}: -"
             for lo, hi, f, t in zip(VELOCITY_EDGES[:-1], VELOCITY_EDGES[1:], found, total, strict=True)]
    print("onset recall at 50 ms by loudest velocity (share of onsets): " + ", ".join(cells))


def table(files_run: list[tuple[list[Hit], list[tuple[float, int]]]]) -> None:
    """Print F, precision and recall per class group at 50 and 30 ms, pooled over files."""
    windows = (0.05, 0.03)
    counts = {w: {g: [0, 0, 0] for g in [*GROUPS, "onsets"]} for w in windows}  # matched, n_ref, n_est
    for hits, found in files_run:
        ref_t = np.array([h.time for h in hits])
        ref_c = np.array([h.cls for h in hits])
        est_t = np.array([t for t, _ in found])
        est_c = np.array([c for _, c in found])
        for w in windows:
            for g, cls in GROUPS.items():
                r = merge(ref_t[np.isin(ref_c, cls)], 1e-4) if len(ref_t) else np.zeros(0)
                e = merge(est_t[np.isin(est_c, cls)], 1e-4) if len(est_t) else np.zeros(0)
                m = len(mir_eval.util.match_events(r, e, w)) if len(r) and len(e) else 0
                c = counts[w][g]
                c[0] += m
                c[1] += len(r)
                c[2] += len(e)
            ro, eo = merge(ref_t), merge(est_t, 1e-4)
            m = len(mir_eval.util.match_events(ro, eo, w)) if len(ro) and len(eo) else 0
            c = counts[w]["onsets"]
            c[0] += m
            c[1] += len(ro)
            c[2] += len(eo)
    print(f"{'class':22s} {'n_ref':>6s} | {'F@50ms':>7s} {'P':>6s} {'R':>6s} | {'F@30ms':>7s} {'P':>6s} {'R':>6s}")
    for g in ["onsets", *GROUPS]:
        row = f"{g:22s} {counts[0.05][g][1]:6d} |"
        for w in windows:
            m, nr, ne = counts[w][g]
            prec = m / ne if ne else 0.0
            rec = m / nr if nr else 0.0
            f = 2 * prec * rec / (prec + rec) if prec + rec else 0.0
            row += f" {f:7.3f} {prec:6.3f} {rec:6.3f} |"
        print(row)


if __name__ == "__main__":
    raise SystemExit(main())
