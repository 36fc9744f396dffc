"""Evaluate the simulated drummer on the Groove MIDI Dataset's validation split; print the aggregate table.

    python bench/evaluate_groove.py                    # a short default subset, cartesian and joint control
                                                       # (4 files of at most 12 s: about 40 s)
    python bench/evaluate_groove.py --all --jobs 2     # the whole validation split (124 files, ~82 min of music)
    python bench/evaluate_groove.py --limit 10 --controls cartesian --renders /tmp/groove-renders

Files: the rows of /work/shared/data/groove/info.csv whose ``split`` is
``validation`` (Gillick et al. 2019, CC BY 4.0), sorted by file name; the
default subset takes ``--limit`` of them (half beats, half fills), evenly
spread over that list among those no longer than ``--max-duration`` seconds
(so the default run stays short). Each file is rendered with every control
mode (``batteur render``'s cores) and evaluated (``batteur evaluate``'s matching and metrics). The goals
of issue 7 are printed under the table; nothing is asserted.
"""

from __future__ import annotations

import argparse
import csv
import json
import multiprocessing
import sys
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

from batteur.evaluate import FileResult, aggregate, evaluate_scores, format_table
from batteur.render import CONTROL_MODES, RenderOptions, check_options
from common.arg_types import count, hertz, seconds
from common.exit_status import report_error
from common.output_paths import check_output_dir, check_output_file, write_atomically

GROOVE = Path("/work/shared/data/groove")
GOALS = ("goals (cartesian): F@25 >= 0.99, median |e| <= 3 ms, p95 |e| <= 10 ms, Spearman >= 0.9 (rho, pooled; rho_s: "
         "within each sound), RTF >= 2")


def validation_rows(root: Path) -> list[dict[str, str]]:
    """info.csv's rows of the validation split, sorted by file name."""
    with (root / "info.csv").open(newline="", encoding="utf-8") as handle:
        rows = [r for r in csv.DictReader(handle) if r["split"] == "validation"]
    return sorted(rows, key=lambda r: r["midi_filename"])


def why_no_files(root: Path, limit: int | None, max_duration: float | None) -> str:
    """Why :func:`validation_files` found none: info.csv lists none, or the filter that removed those it lists
    (``--max-duration 0.1`` said "no validation files found" of a folder holding 124)."""
    rows = validation_rows(root)
    if not rows:
        return f"no validation files in {root} (info.csv has no row whose split is validation)"
    shortest = min(float(r["duration"]) for r in rows)
    if max_duration is not None and shortest > max_duration:
        return (f"none of the {len(rows)} validation files in {root} is within --max-duration {max_duration:g} s "
                f"(the shortest is {shortest:.1f} s; --all takes every one)")
    return (f"--limit {limit} picks none of the {len(rows)} validation files in {root}"
            f"{'' if max_duration is None else f' within --max-duration {max_duration:g} s'} (half beats, half "
            "fills: no file of the kind it takes)")


def validation_files(root: Path, limit: int | None, max_duration: float | None) -> list[tuple[Path, float]]:
    """(path, duration s) of the validation split; with ``limit``, a subset of beats and fills.

    The subset takes half beats, half fills (each evenly spread over the
    file-name order) among the files no longer than ``max_duration`` seconds.
    """
    rows = validation_rows(root)
    if max_duration is not None:
        rows = [r for r in rows if float(r["duration"]) <= max_duration]
    if limit is not None and limit < len(rows):
        picked = []
        for kind, count in (("beat", limit // 2), ("fill", limit - limit // 2)):
            mine = [r for r in rows if r["beat_type"] == kind]
            step = len(mine) / max(count, 1)
            picked += [mine[int(k * step)] for k in range(min(count, len(mine)))]
        rows = sorted(picked, key=lambda r: r["midi_filename"])
    return [(root / r["midi_filename"], float(r["duration"])) for r in rows]


def _evaluate(files: list[tuple[Path, float]], opts: RenderOptions, renders: Path | None, reuse: bool,
              jobs: int) -> list[FileResult]:
    """Render and evaluate every file (longest first over ``jobs`` processes); results in the files' order."""
    paths = [p for p, _ in files]
    if jobs == 1:  # one file at a time, so that a long run shows its progress
        out = []
        for done, path in enumerate(paths, 1):
            out += evaluate_scores([path], opts, renders, quiet=True, reuse=reuse)
            print(f"  [{done}/{len(files)}] {path.name}", file=sys.stderr)
        return out
    order = sorted(range(len(files)), key=lambda k: -files[k][1])  # long files first: the pool ends together
    results: dict[int, FileResult] = {}
    with ProcessPoolExecutor(max_workers=jobs, mp_context=multiprocessing.get_context("spawn")) as pool:
        futures = {pool.submit(evaluate_scores, [paths[k]], opts, renders, True, reuse): k for k in order}
        for done, future in enumerate(as_completed(futures), 1):
            k = futures[future]
            results[k] = future.result()[0]
            print(f"  [{done}/{len(files)}] {paths[k].name}", file=sys.stderr)
    return [results[k] for k in range(len(files))]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--root", type=Path, default=GROOVE,
                        help=f"Groove MIDI Dataset directory, with info.csv (default {GROOVE})")
    parser.add_argument("--all", action="store_true", help="every validation file (long: hours at today's speed)")
    parser.add_argument("--limit", type=count, default=4, help="files in the default subset (default 4)")
    parser.add_argument("--max-duration", type=seconds, default=12.0,
                        help="default subset: only files up to this long, seconds (default 12)")
    parser.add_argument("--controls", default="cartesian,joint",
                        help=f"control modes, comma-separated, of: {', '.join(CONTROL_MODES)} "
                             "(default cartesian,joint)")
    parser.add_argument("--renders", type=Path, default=None, metavar="DIR",
                        help="keep renders in DIR/<control>/<stem> (default: a temporary directory)")
    parser.add_argument("--reuse", action="store_true", help="reuse renders already in --renders")
    parser.add_argument("--calibration", type=Path, default=None, help="calibration JSON applied to the plans")
    parser.add_argument("--json", type=Path, default=None, help="also write every figure to this JSON file")
    parser.add_argument("--control-rate", type=hertz, default=None, metavar="HZ",
                        help="drummer's full control updates per second (default: physics' default)")
    parser.add_argument("--jobs", type=count, default=1,
                        help="render this many files at once, one process each (default 1; wall-clock real-time "
                             "factors then count the sharing, CPU ones do not)")
    return parser


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    """The options, checked before the first render (a bad one otherwise fails after minutes, or hours, of work);
    ``args.controls`` becomes a list."""
    from batteur.calibration import Calibration

    parser = build_parser()
    args = parser.parse_args(argv)
    if not (args.root / "info.csv").is_file():
        parser.error(f"--root {args.root}: no info.csv there (the Groove MIDI Dataset's directory)")
    controls = list(dict.fromkeys(c.strip() for c in args.controls.split(",") if c.strip()))
    unknown = [c for c in controls if c not in CONTROL_MODES]
    if not controls or unknown:
        parser.error(f"--controls {args.controls!r}: {'unknown ' + ', '.join(unknown) if unknown else 'none given'}"
                     f" (choose from {', '.join(CONTROL_MODES)})")
    args.controls = controls
    if args.reuse and args.renders is None:
        parser.error("--reuse needs --renders DIR (the renders to reuse)")
    if args.calibration is not None:
        try:
            Calibration.load(args.calibration)
        except ValueError as exc:
            parser.error(f"--calibration {exc}")
    try:
        check_options(RenderOptions(control_rate_hz=args.control_rate))
        if args.renders is not None:
            check_output_dir(args.renders, "--renders")
        if args.json is not None:
            check_output_file(args.json, "--json")
    except ValueError as exc:
        parser.error(str(exc))
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    limit, max_duration = (None, None) if args.all else (args.limit, args.max_duration)
    files = validation_files(args.root, limit, max_duration)
    if not files:
        return report_error("evaluate_groove", why_no_files(args.root, limit, max_duration))
    music = sum(d for _, d in files)
    print(f"Groove MIDI Dataset validation split: {len(files)} files, {music:.1f} s of music"
          f"{' (all)' if args.all else f' (subset: --limit {args.limit}, --max-duration {args.max_duration:g})'}")
    rows = []
    dump: dict[str, object] = {"files": [str(p) for p, _ in files]}
    for control in args.controls:
        started = time.perf_counter()
        opts = RenderOptions(control=control, calibration=args.calibration, control_rate_hz=args.control_rate)
        renders = args.renders / control if args.renders is not None else None
        results = _evaluate(files, opts, renders, args.reuse, args.jobs)
        agg = aggregate(results)
        rows.append((control, agg))
        dump[control] = {"aggregate": agg, "files": [r.summary() for r in results]}
        print(f"  {control}: {time.perf_counter() - started:.0f} s", file=sys.stderr)
    print(format_table(rows))
    for label, agg in rows:
        t = agg["timing_ms"]
        print(f"{label}: F@10 {agg['f_measure']['10ms']:.3f}, F@25 {agg['f_measure']['25ms']:.3f}, "
              f"median |e| {t['median_abs']} ms, p95 |e| {t['p95_abs']} ms, bias {t['median_signed']} ms, "
              f"Spearman {agg['spearman']} (within each sound {agg['spearman_within_sound']}), "
              f"spurious {agg['spurious']}, missed {agg['missed']} "
              f"{agg['missed_by_reason']}, RTF wall {agg['real_time_factor']} / cpu {agg['real_time_factor_cpu']}")
        print(f"  Spearman per instrument: {agg['spearman_by_instrument']}")
        print(f"  Spearman per sound: {agg['spearman_by_sound']}")
    print(GOALS)
    if args.json is not None:
        write_atomically(args.json, json.dumps(dump, indent=2).encode("utf-8"))
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
