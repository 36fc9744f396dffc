"""Real-time factor of ``batteur render`` (rendered seconds per wall-clock second; goal >= 2).

    python bench/render_speed.py                 # 20 s of a rock groove (short default)
    python bench/render_speed.py --seconds 180   # the 3-minute piece of issue 7
    python bench/render_speed.py --control joint
    python bench/render_speed.py --seconds 180 --jobs 1,2   # one process against two (time segments)

The piece is a text score (hi-hat eighths, snare backbeat, kick, a tom fill
every fourth bar, crash on the downbeat after it) at 100 bpm, repeated to the
requested length. Prints the wall-clock and CPU real-time factors and where
the time goes (each core's step/handle, the bus's encode/decode and the rest),
so the physics can be told what to speed up. With ``--jobs`` above 1 the
render cuts the piece into time segments played on that many processes
(batteur/segments.py); the breakdown is then not timed (the cores run in the
workers). Timing figures on a shared machine are noisy: compare ratios
measured in one run.
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from collections import defaultdict
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from batteur.render import CONTROL_MODES, RenderOptions, check_options, render_score
from common.arg_types import hertz, seconds

BARS = """HH |x.x.x.x.x.x.x.x.|
SN |....X.......X...|
BD |x.......x.x.....|
"""
FILL = """HH |x.x.x.x.........|
SN |....X...xxxx....|
HT |............xx..|
FT |..............xx|
BD |x.......x.......|
"""
CRASH = """CR |X...............|
SN |....X.......X...|
BD |x.......x.x.....|
"""


def piece(seconds: float, bpm: float = 100.0) -> str:
    """A text score about ``seconds`` long (whole bars of 4/4 at ``bpm``)."""
    bars = max(1, math.ceil(seconds / (4 * 60.0 / bpm)))
    blocks = []
    for k in range(bars):
        blocks.append(FILL if k % 4 == 3 else CRASH if k % 4 == 0 and k > 0 else BARS)
    return f"tempo {bpm:g}\nmeter 4/4\n" + "\n".join(blocks)


def instrument(timings: dict[str, float]) -> Callable[[], None]:
    """Wrap the cores' step/handle and the codec to accumulate seconds per part; returns an undo function."""
    from common import bus
    from common.messages import codec
    from services.interaction.core import InteractionCore
    from services.physics.core import PhysicsCore
    from services.sound.core import SoundCore

    undo: list[tuple[Any, str, Any]] = []

    def wrap(owner: Any, name: str, label: str) -> None:
        original = getattr(owner, name)

        def timed(*args: Any, **kwargs: Any) -> Any:
            t0 = time.perf_counter()
            try:
                return original(*args, **kwargs)
            finally:
                timings[label] += time.perf_counter() - t0

        undo.append((owner, name, original))
        setattr(owner, name, timed)

    wrap(PhysicsCore, "step", "physics")
    wrap(InteractionCore, "handle", "interaction")
    wrap(InteractionCore, "step", "interaction")
    wrap(SoundCore, "handle", "sound")
    wrap(SoundCore, "step", "sound")
    wrap(bus, "encode", "bus encode")
    wrap(bus, "decode", "bus decode")
    del codec

    def restore() -> None:
        for owner, name, original in reversed(undo):
            setattr(owner, name, original)

    return restore


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter,
                                     epilog="A run takes about the piece's length divided by the real-time factor "
                                            "(default 20 s: about 20 s; 180 s: about two minutes per --jobs entry).")
    parser.add_argument("--seconds", type=seconds, default=20.0,
                        help="length of the piece, seconds (default 20; issue: 180)")
    parser.add_argument("--control", default="cartesian", choices=list(CONTROL_MODES),
                        help="control mode (default cartesian)")
    parser.add_argument("--control-rate", type=hertz, default=None, metavar="HZ",
                        help="drummer's full control updates per second (default: physics' default)")
    parser.add_argument("--no-breakdown", action="store_true", help="do not time the parts (no wrapper overhead)")
    parser.add_argument("--jobs", default="1",
                        help="processes per render, comma-separated to compare in one run (e.g. 1,2; above 1: "
                        "render --jobs, time segments in parallel; default 1)")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        jobs = [int(j) for j in args.jobs.split(",")]
    except ValueError:
        parser.error(f"--jobs {args.jobs!r}: whole numbers, comma-separated")
    if any(j < 1 for j in jobs):
        parser.error("--jobs: each count must be at least 1")
    try:  # before the render: a rate physics refuses fails there with a traceback
        check_options(RenderOptions(control=args.control, control_rate_hz=args.control_rate))
    except ValueError as exc:
        parser.error(str(exc))
    factors = {n: run_once(args, n) for n in jobs}
    if len(factors) > 1:  # named by the processes each render used: a piece too short to cut runs on one
        base = factors[jobs[0]][0]
        print("wall-clock real-time factors, same run: " + ", ".join(
            f"--jobs {n}: {used} process{'es' if used > 1 else ''} {f:.2f}x ({f / base:.2f} of --jobs {jobs[0]})"
            for n, (f, used) in factors.items()))
    return 0


def run_once(args: argparse.Namespace, jobs: int) -> tuple[float, int]:
    """Render the piece on ``jobs`` processes, print its figures; returns the whole command's wall-clock factor and
    the processes the render used (one for a piece too short to cut in segments)."""
    timings: dict[str, float] = defaultdict(float)
    restore = (lambda: None) if args.no_breakdown or jobs > 1 else instrument(timings)
    with tempfile.TemporaryDirectory(prefix="render-speed-") as tmp:
        score = Path(tmp) / "piece.txt"
        score.write_text(piece(args.seconds), encoding="utf-8")
        t0 = time.perf_counter()
        try:
            opts = RenderOptions(control=args.control, control_rate_hz=args.control_rate, jobs=jobs)
            report = render_score(score, Path(tmp) / "out", opts, quiet=False)  # a bar on a terminal: minutes long
        finally:
            restore()
        wall = time.perf_counter() - t0
    rendered = report["duration_s"]
    cpu = report["cpu_time_s"]
    segments = report["physics"].get("segments")
    used = 1 if segments is None else int(segments["jobs"])
    how = "one process" if segments is None else (
        f"{used} process{'es' if used > 1 else ''}, {segments['count']} segment{'s' if segments['count'] > 1 else ''} "
        f"of {segments['segment_s']:g} s")
    print(f"piece: {report['notes']} notes, {report['music_duration_s']:.1f} s planned, {rendered:.1f} s rendered "
          f"({args.control} control, {report['physics']['rate_hz']:g} Hz physics, {how})")
    print(f"  whole command: wall {wall:.1f} s -> real-time factor {rendered / wall:.2f}x (goal >= 2x); "
          f"render cpu {cpu:.1f} s in all processes ({rendered / cpu:.2f}x per cpu second)")
    print(f"  render loop only (report.json): {report['real_time_factor']}x wall")
    if timings:
        total = report["wall_time_s"]
        print("  where the render loop's wall time goes:")
        parts = dict(timings)
        parts["rest (setup, runner, recorder)"] = max(0.0, total - sum(timings.values()))
        for label, seconds in sorted(parts.items(), key=lambda kv: -kv[1]):
            print(f"    {label:<32} {seconds:7.2f} s  {100 * seconds / total:5.1f} %  "
                  f"({seconds / rendered * 1000:.2f} ms per rendered second)")
    return rendered / wall, used


if __name__ == "__main__":
    raise SystemExit(main())
