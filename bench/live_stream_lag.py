"""How late a live core plays a streamed hand when its loop comes back late, and after one long skip.

    python3 bench/live_stream_lag.py            # about a minute (12 runs of 1.8 s of drummer simulation)

A live drummer core stepped to rig time 2 s by a clock that comes back 20-70 ms late at every call (the core
simulates 50 steps and skips the rest), its left hand swaying 0.1 m at 2 Hz streamed a knot every 10 / 50 / 250 ms,
200 ms ahead (300 ms for 250 ms knots); with no longer skip, or one call 0.2 / 0.3 / 0.5 s later still at rig time
1 s. The driver is tests/physics/live_stream.py (the tests' own, tests/physics/test_live_lag_bound.py). Printed per
run: how late the streamed knot in use plays (the lag grown since it was placed), mean / max over the run and mean
over the 0.6 s of rig time after the long skip; the hand target's distance from what was asked for the rig time,
mean / max. Deterministic: no wall clock is read. Figures are printed, never asserted.

To compare with an older tree, copy this file and tests/physics/live_stream.py into a worktree of it and run it
there (the driver reads the core's ``_streamed`` knots by index only).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.physics.live_stream import follow_dense_stream, live_core  # noqa: E402

SPACINGS_S = (0.01, 0.05, 0.25)
"""Knot spacings, s ..."""
AHEAD_S = {0.01: 0.2, 0.05: 0.2, 0.25: 0.3}
"""... and how far ahead each stream sends, s."""
SKIPS_S = (None, 0.2, 0.3, 0.5)
"""The one longer skip at ``SKIP_AT_S``: seconds, or none."""
SKIP_AT_S, AFTER_S, END_S = 1.0, 0.6, 2.0
"""Rig time of the longer skip, the span after it measured apart, and the run's end, s."""


def measure(spacing_s: float, skip_s: float | None) -> str:
    """One run's cell: lateness mean / max (ms), mean after the skip (ms), distance mean / max (mm)."""
    core = live_core()
    try:
        run = follow_dense_stream(core, spacing_s, AHEAD_S[spacing_s], END_S,
                                  long_skip=None if skip_s is None else (SKIP_AT_S, skip_s))
    finally:
        core.close()
    late = np.array(run.lateness()) * 1e3
    cell = f"{late.mean():.0f} / {late.max():.0f} ms"
    if skip_s is not None:
        after = np.array(run.lateness(SKIP_AT_S, SKIP_AT_S + skip_s + AFTER_S)) * 1e3
        cell += f" (after: {after.mean():.0f})"
    far = np.array(run.far) * 1e3
    return cell + f", {far.mean():.0f} / {far.max():.0f} mm"


def main(argv: Sequence[str] | None = None) -> None:
    argparse.ArgumentParser(
        prog="python3 bench/live_stream_lag.py",
        description="How late a live core plays a streamed hand when its loop comes back 20-70 ms late, and after "
                    "one longer skip (none, 0.2, 0.3, 0.5 s), for knots streamed every 10, 50 and 250 ms: a Markdown "
                    "table, about a minute (12 runs of 1.8 s of drummer simulation). Deterministic; takes no "
                    "options.").parse_args(argv)
    print("| longer skip | " + " | ".join(f"{s * 1e3:.0f} ms knots" for s in SPACINGS_S) + " |")
    print("|---" * (len(SPACINGS_S) + 1) + "|")
    for skip_s in SKIPS_S:
        cells = [measure(spacing_s, skip_s) for spacing_s in SPACINGS_S]
        label = "none" if skip_s is None else f"{skip_s:.1f} s"
        print(f"| {label} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
