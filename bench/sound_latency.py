"""Strike-to-output latency of the sound service: distribution, late strikes, real-time margin.

    python bench/sound_latency.py            # no options; part 2 runs 5 s on the wall clock

1. Scheduling (deterministic, simulated network): impacts at random rig times
   reach the core after a random network delay (log-normal, median 2 ms, long
   tail) while the core renders in lockstep with the rig clock. For several
   latency windows, prints the distribution of (first output sample time -
   impact time) and the fraction of late strikes. With a window longer than
   the delay plus one block every strike comes out exactly ``latency`` after
   its impact, to the sample.
2. Live pacing (wall clock): the core is stepped every block period on the
   wall clock with the full kit playing; for every strike, prints how long
   before its output time the block holding it was ready (the margin the
   sound card's buffer gets), and the render time per block.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402
from collections.abc import Sequence  # noqa: E402

import numpy as np  # noqa: E402

from common.messages import Impact  # noqa: E402
from services.sound.core import SoundCore, SoundSettings  # noqa: E402

INSTRUMENTS = ["kick", "snare", "hightom", "floortom", "hihat", "crash", "ride", "cowbell"]
SR = 48000


def make_impact(seq: int, t: float, rng: np.random.Generator) -> Impact:
    return Impact(seq=seq, time=t, instrument=str(rng.choice(INSTRUMENTS)), zone="centre", r=0.4, theta=0.2,
                  velocity=float(rng.uniform(1.0, 6.0)), impulse=0.0, peak_force=0.0, duration=0.002, part="stick")


def scheduling(latency: float, n: int = 300, seed: int = 3) -> tuple[np.ndarray, int]:
    """(output latency per strike in seconds, late count) with simulated network delays."""
    rng = np.random.default_rng(seed)
    times = np.sort(rng.uniform(0.2, 10.0, n))
    delays = rng.lognormal(np.log(0.002), 0.8, n)
    arrivals = sorted(zip(times + delays, times, range(n), strict=True))
    core = SoundCore(SoundSettings(latency=latency, use_pyo=False, record=False))
    try:
        for arrival, t, seq in arrivals:
            core.render(arrival)  # the rig clock has reached the arrival time
            core.handle(make_impact(seq, float(t), rng), arrival, "net")
        core.render(times[-1] + latency + 0.2)
        late = core.late
    finally:
        core.close()
    # the core records when each strike's first sample is output (tests check that this is where the sound starts)
    return np.asarray(core.strike_latencies, dtype=np.float64), late


def live(seconds: float = 5.0, latency: float = 0.02, seed: int = 5) -> None:
    rng = np.random.default_rng(seed)
    core = SoundCore(SoundSettings(latency=latency, record=False, render_ahead=2 * 256 / SR + 0.002))
    block = core.block / SR
    pending = sorted(rng.uniform(0.1, seconds - 0.1, int(10 * seconds)))
    seq = 0
    ready: dict[int, float] = {}
    render_times = []
    try:
        t0 = time.perf_counter()
        next_tick = t0
        strike_targets: dict[int, float] = {}
        while True:
            now = time.perf_counter() - t0
            if now > seconds:
                break
            while pending and pending[0] <= now:
                t = pending.pop(0)
                core.handle(make_impact(seq, t, rng), now, "net")
                strike_targets[seq] = t + latency
                seq += 1
            c0 = time.perf_counter()
            core.step(now)
            done = time.perf_counter()
            render_times.append(done - c0)
            rendered_until = core.now
            for s, target in strike_targets.items():
                if s not in ready and target < rendered_until:
                    ready[s] = target - (done - t0)  # margin: output time minus when it was ready
            next_tick += block
            time.sleep(max(0.0, next_tick - time.perf_counter()))
    finally:
        core.close()
    margins = np.asarray(list(ready.values())) * 1e3
    rt = np.asarray(render_times) * 1e3
    print(f"live pacing, latency {latency * 1e3:.0f} ms, {len(margins)} strikes, {core.late} late: "
          f"ready before output by median {np.median(margins):.1f} ms, min {np.min(margins):.1f} ms, "
          f"in time for {np.mean(margins > 0):.0%}; "
          f"step time median {np.median(rt):.3f} ms p99 {np.percentile(rt, 99):.3f} ms "
          f"(block {block * 1e3:.2f} ms)")


def build_parser() -> argparse.ArgumentParser:
    return argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)


def main(argv: Sequence[str] | None = None) -> int:
    build_parser().parse_args(argv)
    print("1. scheduling with simulated network delay (log-normal, median 2 ms)")
    for latency in (0.003, 0.01, 0.02, 0.05):
        lat, late = scheduling(latency)
        ms = lat * 1e3
        print(f"  window {latency * 1e3:5.1f} ms: strike-to-output latency median {np.median(ms):.3f} ms, "
              f"p99 {np.percentile(ms, 99):.3f} ms, max {np.max(ms):.3f} ms, "
              f"exactly the window (+-1 sample) for {np.mean(np.abs(ms - latency * 1e3) <= 1e3 / SR):.1%}; "
              f"late {late}/{lat.shape[0]}")
    print("2. live pacing on the wall clock, full kit")
    live()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
