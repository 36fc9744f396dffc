"""``batteur render``: run the services' cores together offline and write the results.

Today it renders the strike scene (the first end-to-end strike: a stick thrown
onto a kit instrument on a schedule); scores come with the full drummer.
Outputs in DIR: performance.wav, impacts.csv (one row per impact) and
report.json. Nothing is written unless the run succeeds.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import soundfile as sf

from batteur.impact_log import write_impacts_csv
from batteur.progress import Progress
from batteur.strike import DEFAULT_STRIKES, parse_strikes, run_strikes
from common.kit import EventType, load_kit


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="batteur render",
        description="Render offline through the same cores as the rig (physics -> interaction -> sound). "
        "Writes DIR/performance.wav, DIR/impacts.csv and DIR/report.json.",
    )
    parser.add_argument("-o", "--output", type=Path, required=True, help="output directory (created if missing)")
    parser.add_argument("--strikes", default=",".join(f"{t:g}:{v:g}" for t, v in DEFAULT_STRIKES),
                        help="strike scene schedule TIME:SPEED,... in seconds:m/s (default: %(default)s)")
    parser.add_argument("--event", default="SNARE", choices=[e.value for e in EventType if e != EventType.HIHATPEDAL],
                        help="which kit event the stick strikes (default SNARE)")
    parser.add_argument("--kit", default="default", help="kit name or YAML/JSON file (default: default)")
    parser.add_argument("--latency", type=float, default=0.05, help="sound latency window, seconds (default 0.05)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    opts = build_parser().parse_args(argv)
    try:
        strikes = parse_strikes(opts.strikes)
        kit = load_kit(opts.kit)
    except (ValueError, FileNotFoundError) as exc:
        print(f"batteur render: {exc}", file=sys.stderr)
        return 2
    started = time.monotonic()
    progress = Progress("rendering", max(t for t, _ in strikes) + opts.latency + 1.0,
                        enabled=False if opts.quiet else None)
    try:
        result = run_strikes(strikes, EventType(opts.event), kit, opts.latency,
                             on_progress=lambda t, total: progress.update(t))
    except ValueError as exc:
        print(f"batteur render: {exc}", file=sys.stderr)
        return 2
    finally:
        progress.close()
    elapsed = time.monotonic() - started
    report = {
        "scene": "strike",
        "event": opts.event,
        "strikes": [{"time_s": t, "speed_m_s": v} for t, v in strikes],
        "impacts": len(result.impacts),
        "contacts": result.contacts,
        "duration_s": result.duration_s,
        "sample_rate_hz": result.sample_rate,
        "latency_s": opts.latency,
        "wall_time_s": round(elapsed, 3),
        "real_time_factor": round(result.duration_s / elapsed, 2) if elapsed > 0 else None,
    }
    # write into a temporary directory first so a failure leaves nothing partial
    opts.output.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=opts.output) as tmp:
        staging = Path(tmp)
        sf.write(staging / "performance.wav", result.audio, result.sample_rate, subtype="PCM_24")
        write_impacts_csv(result.impacts, staging / "impacts.csv")
        (staging / "report.json").write_text(json.dumps(report, indent=2), encoding="utf-8")
        for item in staging.iterdir():
            item.replace(opts.output / item.name)
    print(f"wrote {opts.output / 'performance.wav'}")
    print(f"wrote {opts.output / 'impacts.csv'} ({len(result.impacts)} impacts)")
    print(f"wrote {opts.output / 'report.json'}")
    return 0
