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
    python bench/recogniser_bench.py --losses   # also: where the onset F-measure is lost, and bounds on decoding
    python bench/recogniser_bench.py --onset-merge 0.03   # onsets counted as madmom's evaluation combines them

Several ``--model`` files are scored on the same renders, each file transcribed by each model in turn
(so their speeds are measured under the same load).
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import mir_eval  # noqa: E402

from common.arg_types import count, seconds  # noqa: E402
from common.exit_status import report_error  # noqa: E402
from common.messages.recogniser import DrumHit  # noqa: E402
from services.recogniser.audio import SAMPLE_RATE, resample  # noqa: E402
from services.recogniser.classes import CLASS_NAMES, class_of_note  # noqa: E402
from services.recogniser.core import LiveRecogniser  # noqa: E402
from services.recogniser.errors import ModelError  # noqa: E402
from services.recogniser.framenet import FrameNet  # noqa: E402
from services.recogniser.model import MODEL_PATH, Model, load_model  # noqa: E402
from services.recogniser.training.dataset import GrooveMissingError, groove_files, require_groove  # noqa: E402
from services.recogniser.training.frames import ONSET_MERGE_S, onset_times  # noqa: E402
from services.recogniser.training.kits import (  # noqa: E402
    DRUMKITS_DIR,
    RENDER_RATE,
    TEST_KITS,
    TRAIN_KITS,
    VALID_KITS,
    KitsMissingError,
    load_kit,
    require_kits,
)
from services.recogniser.training.render import Hit, Note, augment, normalise, read_notes, render  # noqa: E402
from services.recogniser.transcribe import (  # noqa: E402
    PEAK,
    DrumEvent,
    group_chords,
    network_outputs,
    strikes,
    transcribe,
)

GROUPS: dict[str, tuple[int, ...]] = {name: (i,) for i, name in enumerate(CLASS_NAMES)}
GROUPS["hihat (open+closed)"] = (2, 3)
GROUPS["toms (all)"] = (4, 5, 6)


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--files", type=count, default=None,
                    help="performances drawn at random from the split (default: all of them)")
    ap.add_argument("--seconds", type=seconds, default=None,
                    help="at most this much of each, seconds (default: the whole performance)")
    ap.add_argument("--kit", default=TEST_KITS[0], help="hydrogen kit to render with (default: the held-out one)")
    ap.add_argument("--split", default="validation", choices=("validation", "train", "test"),
                    help="Groove split to render (default validation; use train with --kit of VALID_KITS to tune)")
    ap.add_argument("--augment", action="store_true", help="add room, EQ and noise as in training")
    ap.add_argument("--model", type=Path, nargs="+", default=[MODEL_PATH],
                    help="model file(s) to score; several are scored on the same renders (default: the shipped one)")
    ap.add_argument("--seed", type=int, default=7, help="seed of the file draw and the renders, 0 or more (default 7)")
    ap.add_argument("--live", action="store_true", help="also score the live core (fed 128-sample blocks)")
    ap.add_argument("--onset-merge", type=seconds, default=ONSET_MERGE_S, metavar="S",
                    help="reference strikes within S seconds of an onset's first strike are one class-agnostic onset "
                         f"(default {ONSET_MERGE_S}, as the trainer counts them; madmom's onset evaluation combines "
                         "annotations within 0.03 s)")
    ap.add_argument("--losses", action="store_true",
                    help="also count where the class-agnostic onsets are lost (missed and extra onsets by cause) and "
                         "what the network's strikes would score with an ideal chord grouping or exact times")
    return ap


def parse_args(argv: list[str] | None = None, ap: argparse.ArgumentParser | None = None) -> argparse.Namespace:
    """The options, checked (``ap.error``) before anything is rendered."""
    ap = ap or build_parser()
    args = ap.parse_args(argv)
    if args.seed < 0:
        ap.error(f"--seed {args.seed}: 0 or more")
    installed = sorted(d.name for d in DRUMKITS_DIR.glob("*") if (d / "drumkit.xml").is_file())
    if installed and args.kit not in installed:  # the kits are there, the name is not one of them
        ap.error(f"--kit {args.kit!r}: no such hydrogen kit in {DRUMKITS_DIR} (installed: {', '.join(installed)})")
    return args


def main(argv: list[str] | None = None) -> int:
    ap = build_parser()
    args = parse_args(argv, ap)
    try:
        require_kits([args.kit])
    except KitsMissingError as exc:
        return report_error(ap.prog, exc)  # its line starts with the program's name, as argparse's errors
    try:  # no dataset was a traceback; a split with no file an empty run (this machine's copy has no test split)
        require_groove((args.split,))
    except GrooveMissingError as exc:
        return report_error(ap.prog, exc)
    try:
        models = [load_model(p) for p in args.model]
    except ModelError as exc:  # a file it cannot use: 1, as every command (README, "Exit status")
        return report_error(ap.prog, f"--model {exc}")
    for path, model in zip(args.model, models, strict=True):
        if args.kit in set(model.meta.get("trained_on", TRAIN_KITS)):
            print(f"{ap.prog}: warning: {args.kit} was used for training {path}", file=sys.stderr)
    kit = load_kit(args.kit)
    rng = np.random.default_rng(args.seed)
    files = groove_files(args.split)
    wanted = len(files) if args.files is None else min(args.files, len(files))
    picks = rng.choice(len(files), size=wanted, replace=False)
    longest = np.inf if args.seconds is None else args.seconds
    runs: list[dict[str, list[tuple[list[Hit], list[tuple[float, int]]]]]] = [
        {"offline": [], "live": []} for _ in models]
    outputs: list[list[tuple[list[Hit], np.ndarray]]] = [[] for _ in models]  # with --losses
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
            out = network_outputs(audio, model.offline, sample_rate=RENDER_RATE)  # transcribe(), in its two parts
            events = strikes(model.offline, out)
            compute_s[i] += time.perf_counter() - t0
            if args.losses:
                outputs[i].append((hits, out))
            runs[i]["offline"].append((hits, [(e.time, e.cls) for e in events]))
            if args.live:
                runs[i]["live"].append((hits, live_hits(model, live_audio, latencies[i])))

    print(file=sys.stderr)
    if not audio_s:  # every file drawn starts after --seconds: nothing rendered, nothing to score
        drawn = f"the {len(picks)} {args.split} file{'s' if len(picks) > 1 else ''} drawn (nothing to score)"
        return report_error(ap.prog, f"no notes in {drawn}" if args.seconds is None
                            else f"--seconds {args.seconds:g}: no note that early in {drawn}")
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
                table(files_run, args.onset_merge)
                soft_recall(files_run, merge_s=args.onset_merge)
        if outputs[i]:
            onset_losses(model.offline, outputs[i], args.onset_merge)
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


def soft_recall(files_run: list[tuple[list[Hit], list[tuple[float, int]]]], window: float = 0.05,
                merge_s: float = ONSET_MERGE_S) -> None:
    """Print the class-agnostic onset recall by the loudest MIDI velocity of the onset's strikes (reference strikes
    within ``merge_s`` seconds of an onset's first strike are one onset)."""
    found = np.zeros(len(VELOCITY_EDGES) - 1)
    total = np.zeros(len(VELOCITY_EDGES) - 1)
    for hits, est in files_run:
        order = sorted(hits, key=lambda h: h.time)
        onsets: list[list[float]] = []  # [time, loudest velocity]
        for h in order:
            if onsets and h.time - onsets[-1][0] <= merge_s:
                onsets[-1][1] = max(onsets[-1][1], h.velocity)
            else:
                onsets.append([h.time, h.velocity])
        ref = np.array([o[0] for o in onsets])
        vel = np.array([o[1] for o in onsets])
        e = onset_times(np.array([t for t, _ in est]), 1e-4)
        hit = np.zeros(len(ref), bool)
        if len(ref) and len(e):
            hit[[i for i, _ in mir_eval.util.match_events(ref, e, window)]] = True
        b = np.digitize(vel, VELOCITY_EDGES) - 1
        np.add.at(total, b, 1)
        np.add.at(found, b, hit)
    cells = [f"{lo}-{hi - 1}: {f / t:.2f} ({t / total.sum():.0%})" if t else f"{lo}-{hi - 1}: -"
             for lo, hi, f, t in zip(VELOCITY_EDGES[:-1], VELOCITY_EDGES[1:], found, total, strict=True)]
    print("onset recall at 50 ms by loudest velocity (share of onsets): " + ", ".join(cells))


def table(files_run: list[tuple[list[Hit], list[tuple[float, int]]]], merge_s: float = ONSET_MERGE_S) -> None:
    """Print F, precision and recall per class group at 50 and 30 ms, pooled over files; the class-agnostic
    onsets count reference strikes within ``merge_s`` seconds of an onset's first strike as one onset."""
    windows = (0.05, 0.03)
    counts = {w: {g: [0, 0, 0] for g in [*GROUPS, "onsets"]} for w in windows}  # matched, n_ref, n_est
    for hits, found in files_run:
        ref_t = np.array([h.time for h in hits])
        ref_c = np.array([h.cls for h in hits])
        est_t = np.array([t for t, _ in found])
        est_c = np.array([c for _, c in found])
        for w in windows:
            for g, cls in GROUPS.items():
                r = onset_times(ref_t[np.isin(ref_c, cls)], 1e-4) if len(ref_t) else np.zeros(0)
                e = onset_times(est_t[np.isin(est_c, cls)], 1e-4) if len(est_t) else np.zeros(0)
                m = len(mir_eval.util.match_events(r, e, w)) if len(r) and len(e) else 0
                c = counts[w][g]
                c[0] += m
                c[1] += len(r)
                c[2] += len(e)
            ro, eo = onset_times(ref_t, merge_s), onset_times(est_t, 1e-4)
            m = len(mir_eval.util.match_events(ro, eo, w)) if len(ro) and len(eo) else 0
            c = counts[w]["onsets"]
            c[0] += m
            c[1] += len(ro)
            c[2] += len(eo)
    if merge_s != ONSET_MERGE_S:
        print(f"(onsets: reference strikes within {merge_s * 1000:g} ms of an onset's first strike are one onset)")
    print(f"{'class':22s} {'n_ref':>6s} | {'F@50ms':>7s} {'P':>6s} {'R':>6s} | {'F@30ms':>7s} {'P':>6s} {'R':>6s}")
    for g in ["onsets", *GROUPS]:
        row = f"{g:22s} {counts[0.05][g][1]:6d} |"
        for w in windows:
            m, nr, ne = counts[w][g]
            prec = m / ne if ne else 0.0
            rec = m / nr if nr else 0.0
            f = 2 * prec * rec / (prec + rec) if prec + rec else 0.0
            # undefined (nothing found: no precision; nothing played: no recall) is "-", not a 0.000 like a miss
            row += (f" {'-' if not nr and not ne else f'{f:.3f}':>7} {f'{prec:.3f}' if ne else '-':>6} "
                    f"{f'{rec:.3f}' if nr else '-':>6} |")
        print(row)


NEIGHBOUR_S = 0.05
"""A reference onset with another this close (seconds) is "close": two strikes the 50 ms window cannot tell apart
by time alone."""
FOUND_S = 0.015
"""A missed onset counts as found-but-merged when a strike of one of its classes, before chord grouping, lies
this close to it, seconds."""


def onset_scores(ref: np.ndarray, est: np.ndarray, window: float = 0.05) -> tuple[int, int, int]:
    """(matched, reference onsets, estimated onsets) of mir_eval's one-to-one matching; ``ref`` is already merged
    (:func:`onset_times`), ``est`` is merged only where times coincide, as :func:`table` scores onsets."""
    e = onset_times(est, 1e-4) if len(est) else np.zeros(0)
    m = len(mir_eval.util.match_events(ref, e, window)) if len(ref) and len(e) else 0
    return m, len(ref), len(e)


def ideal_grouping(ref: np.ndarray, est: np.ndarray, window: float = 0.05,
                   merge_s: float = ONSET_MERGE_S) -> tuple[int, int, int]:
    """(matched, reference onsets, estimated onsets) if every strike within ``window`` of a reference onset
    were grouped into that onset's estimate (a grouping that knows the answer); the strikes near none stay,
    grouped as the reference is (strikes within ``merge_s`` seconds one onset). An upper bound for any rule that
    groups these strikes."""
    e = np.sort(est)
    pairs = mir_eval.util.match_events(ref, e, window) if len(ref) and len(e) else []
    used = {j for _, j in pairs}
    stray = np.array([t for j, t in enumerate(e) if j not in used and (not len(ref) or np.abs(ref - t).min() > window)])
    return len(pairs), len(ref), len(pairs) + len(onset_times(stray, merge_s))


def exact_times(hits: list[Hit], events: list[tuple[float, int]], within: float = FOUND_S) -> list[tuple[float, int]]:
    """``events`` (time s, class) with each time moved onto the nearest reference strike of its class within
    ``within`` seconds (the others unchanged): the strikes with the times an ideal network would give them."""
    by_class = {c: np.array([h.time for h in hits if h.cls == c]) for c in {h.cls for h in hits}}
    moved = []
    for t, c in events:
        ref = by_class.get(c, np.zeros(0))
        if len(ref):
            near = float(ref[np.abs(ref - t).argmin()])
            t = near if abs(near - t) <= within else t
        moved.append((t, c))
    return moved


def chord_times(events: list[tuple[float, int]], window: float) -> np.ndarray:
    """Times of ``events`` (time s, class) after the transcriber's chord grouping (:func:`group_chords`)."""
    dummies = [DrumEvent(t, c, 64, 1.0) for t, c in sorted(events)]
    return np.array([e.time for e in group_chords(dummies, window)] if window > 0 else [e.time for e in dummies])


def onset_losses(net: FrameNet, files: list[tuple[list[Hit], np.ndarray]], merge_s: float = ONSET_MERGE_S) -> None:
    """Print where the class-agnostic onset F-measure at 50 ms is lost, for ``net``'s outputs on ``files``
    (reference hits, :func:`network_outputs`): missed onsets and extra onsets by cause, and what the same strikes
    score (1) with an ideal chord grouping, (2) with exact times and the chord grouping used."""
    loose = replace(net, chord_s=0.0)
    totals = {k: np.zeros(3, int) for k in ("as decoded", "ideal grouping", "exact times")}
    missed = {k: 0 for k in ("close, found but given a neighbour's time", "close, not found", "alone, not found",
                             "alone, found")}
    extra = {"near a reference onset (a second estimate for it)": 0, "far from every reference onset": 0}
    for hits, out in files:
        ref_t = np.array([h.time for h in hits])
        ref_c = np.array([h.cls for h in hits])
        ref = onset_times(ref_t, merge_s) if len(ref_t) else np.zeros(0)
        decoded = np.array([e.time for e in strikes(net, out)])
        raw = [(e.time, e.cls) for e in strikes(loose, out)]
        raw_t = np.array([t for t, _ in raw])
        est = onset_times(decoded, 1e-4) if len(decoded) else np.zeros(0)
        pairs = mir_eval.util.match_events(ref, est, 0.05) if len(ref) and len(est) else []
        totals["as decoded"] += (len(pairs), len(ref), len(est))
        totals["ideal grouping"] += ideal_grouping(ref, raw_t, merge_s=merge_s)
        totals["exact times"] += onset_scores(ref, chord_times(exact_times(hits, raw), net.chord_s))
        hit_ref, hit_est = {i for i, _ in pairs}, {j for _, j in pairs}
        for i, t in enumerate(ref):
            if i in hit_ref:
                continue
            others = np.abs(np.delete(ref, i) - t)
            close = bool(len(others)) and float(others.min()) < NEIGHBOUR_S
            classes = set(ref_c[(ref_t >= t) & (ref_t <= t + merge_s)].tolist())
            found = any(abs(rt - t) <= FOUND_S for rt, c in raw if c in classes)
            key = ("close, found but given a neighbour's time" if found else "close, not found") if close else (
                "alone, found" if found else "alone, not found")
            missed[key] += 1
        for j, t in enumerate(est):
            if j not in hit_est:
                near = bool(len(ref)) and float(np.abs(ref - t).min()) <= 0.05
                extra["near a reference onset (a second estimate for it)" if near
                      else "far from every reference onset"] += 1
    n_ref = int(totals["as decoded"][1])
    print(f"\nwhere the onsets are lost (F at 50 ms; {n_ref} reference onsets, strikes closer than "
          f"{merge_s * 1000:g} ms one onset):")
    for name, (m, nr, ne) in totals.items():
        prec, rec = m / max(ne, 1), m / max(nr, 1)
        f = 2 * prec * rec / (prec + rec) if prec + rec else 0.0
        print(f"  {name:15s} F {f:.3f} (P {prec:.3f} / R {rec:.3f})")
    print(f"  missed onsets: {sum(missed.values())}, of them " + "; ".join(f"{k} {v}" for k, v in missed.items()))
    print(f"  extra onsets: {sum(extra.values())}, of them " + "; ".join(f"{k} {v}" for k, v in extra.items()))


if __name__ == "__main__":
    raise SystemExit(main())
