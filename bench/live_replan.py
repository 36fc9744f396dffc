"""Live notes over a playing score: does re-planning stall the live physics loop?

    python bench/live_replan.py            # background plans (the live node), then --sync, one sitting
    python bench/live_replan.py --mode background --lead 0.5 --switch-interval 0.001

Runs the physics core as the live node does: the node's RateLoop (common/runtime.py) steps it at 1 kHz
against the wall clock in an asyncio loop, and the live notes are handed to ``core.handle`` on that same
thread, as the node's datagram handler does. The drummer plays the 55 s Groove file
(tests/data/groove_drummer6_s3_1_rock_90_beat_4-4.mid, 439 notes) from rig time 1 s; from 3 s, a crash
note (not in the score) arrives every ``--period`` seconds for ``--seconds``, each ``--lead`` seconds
ahead of its time. Printed per mode: the loop's longest gap between steps and its 99th percentile over the
live-note window (wall ms), physics steps skipped (more than 50 behind), the loop's overruns, live notes
late (counted, not played) and played (a crash contact within 30 ms of the note), planning time per live
note. ``sync``: plain PhysicsCore, planning in the handler (the old node); ``background``: the node's
LivePhysicsCore. Timing on a shared machine is noisy: compare the two modes within one run.
"""

from __future__ import annotations

import argparse
import asyncio
import gc
import math
import statistics
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from common.arg_types import seconds
from common.messages import Contact
from common.messages.score import LiveNote, ScoreLoad, ScoreTransport
from common.runtime import RateLoop
from services.physics.core import PhysicsCore, PhysicsSettings
from services.physics.node import LivePhysicsCore
from services.physics.plan_worker import PlanWorker
from services.physics.precompile import warm_up

MIDI = Path(__file__).parents[1] / "tests" / "data" / "groove_drummer6_s3_1_rock_90_beat_4-4.mid"
CRASH = 49
"""GM Crash Cymbal 1: the live notes' pitch (the score has none)."""
PLAY_AT_S = 1.0
FIRST_NOTE_S = 3.0


def run(mode: str, window_s: float, period_s: float, lead_s: float, planner: PlanWorker) -> dict[str, float]:
    """One live run; returns its figures."""
    settings = PhysicsSettings(scene="drummer", grip="german", mode="live")
    core = LivePhysicsCore(settings, planner=planner) if mode == "background" else PhysicsCore(settings)
    player = core.score_player
    player.library = [MIDI.parent]
    _ = player.preparation_s  # the gesture database, loaded before the clock starts (as the node does)
    core.handle(ScoreLoad(path=MIDI.name), 0.0, "bench")
    gc.collect()
    gc.freeze()  # as the node does once started: full collections no longer walk the setup's heap
    try:
        return asyncio.run(_drive(core, window_s, period_s, lead_s))
    finally:
        core.close()


async def _drive(core: PhysicsCore, window_s: float, period_s: float, lead_s: float) -> dict[str, float]:
    player = core.score_player
    start = time.monotonic()
    ticks: list[float] = []
    notes: list[float] = []
    crashes: list[float] = []
    handler_s: list[float] = []
    durations: list[tuple[float, float]] = []

    def now() -> float:
        return time.monotonic() - start

    def tick() -> None:
        t = now()
        ticks.append(t)
        t0 = time.perf_counter()
        outgoing = core.step(t)
        durations.append((t, time.perf_counter() - t0))
        for out in outgoing:
            if isinstance(out.message, Contact) and out.message.instrument == "crash":
                if not crashes or out.message.time - crashes[-1] > 0.015:
                    crashes.append(out.message.time)

    loop = RateLoop(1000.0, tick, max_catch_up=10)  # as the node's: 10 ms of back-to-back ticks at most
    task = asyncio.create_task(loop.run())
    end = FIRST_NOTE_S + window_s
    await asyncio.sleep(0.5)
    core.handle(ScoreTransport(action="play", time=PLAY_AT_S, position=0.0), now(), "bench")
    await asyncio.sleep(FIRST_NOTE_S - now())
    skipped0, overruns0, late0 = core.skipped_steps, loop.overruns, player.late_notes
    k = 0
    while k == 0 or now() < end:  # at least one note: a stall past a short window sent none (an empty max())
        t = FIRST_NOTE_S + k * period_s
        await asyncio.sleep(max(0.0, t - now()))
        sent = now()
        notes.append(sent + lead_s)
        t0 = time.perf_counter()
        core.handle(LiveNote(time=sent + lead_s, pitch=CRASH, velocity=110, channel=10), sent, "bench")
        handler_s.append(time.perf_counter() - t0)
        k += 1
    await asyncio.sleep(lead_s + 0.5)
    loop.stop()
    await task
    # gaps and step calls overlapping the live-note window (one stall may span a short window: none began in it)
    window = [b - a for a, b in zip(ticks, ticks[1:], strict=False) if a <= end + lead_s and b >= FIRST_NOTE_S]
    longest_tick = max((d for t, d in durations if t <= end + lead_s and t + d >= FIRST_NOTE_S), default=0.0)
    played = sum(1 for n in notes if any(abs(c - n) <= 0.03 for c in crashes))
    # background plans' seconds per note: the player's own history (plans of 20 notes or more) and the shorter ones
    times = list(getattr(player, "_plan_times", []))
    times += [took / notes for notes, took in getattr(player, "_short_plan_times", []) if notes]
    return {"notes": len(notes), "max_gap_ms": 1000 * max(window), "p99_gap_ms": 1000 * _p99(window),
            "skipped_steps": core.skipped_steps - skipped0, "overruns": loop.overruns - overruns0,
            "late": player.late_notes - late0, "tick_max_ms": 1000 * longest_tick, "played": played,
            "handler_max_ms": 1000 * max(handler_s),
            "ms_per_note": 1000 * statistics.median(times) if times else float("nan"),
            "replanned_late": player.replanned_late}


def planning(mode: str, ms_per_note: float) -> str:
    """The planning time per note, or where it is: sync plans in the handler (its time is the handler's)."""
    if mode == "sync":
        return "planning in the handler"
    return "no plan timed" if math.isnan(ms_per_note) else f"planning {ms_per_note:.2f} ms/note"


def _p99(values: list[float]) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(0.99 * len(ordered)))]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--mode", choices=("both", "sync", "background"), default="both",
                        help="sync: planning in the handler; background: the live node's planner; both: background "
                             "then sync (default both)")
    parser.add_argument("--seconds", type=seconds, default=10.0, help="live notes for this long, s (default 10)")
    parser.add_argument("--period", type=seconds, default=0.5,
                        help="a live note every this many seconds (default 0.5)")
    parser.add_argument("--lead", type=seconds, default=1.0, help="each note this long after it is sent, s (default 1)")
    parser.add_argument("--switch-interval", type=seconds, default=None,
                        help="sys.setswitchinterval for the run, s (default: Python's, 0.005)")
    parser.add_argument("--sync", action="store_true", help="the same as --mode sync")
    parser.add_argument("--planner", choices=("process", "thread"), default="process",
                        help="background: where plans run (default process, as the node)")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.sync and args.mode not in ("both", "sync"):  # --sync used to override --mode background silently
        parser.error(f"--sync is --mode sync: not with --mode {args.mode}")
    if args.switch_interval:
        sys.setswitchinterval(args.switch_interval)
    warm_up()
    modes = ["sync"] if args.sync else ["background", "sync"] if args.mode == "both" else [args.mode]
    print(f"planner {args.planner}, switch interval {sys.getswitchinterval() * 1000:g} ms, lead {args.lead:g} s, "
          f"a note every {args.period:g} s for {args.seconds:g} s")
    for mode in modes:
        r = run(mode, args.seconds, args.period, args.lead, args.planner)
        print(f"{mode:>10}: longest step gap {r['max_gap_ms']:.1f} ms (99th pct {r['p99_gap_ms']:.2f} ms), "
              f"longest step call {r['tick_max_ms']:.1f} ms, steps skipped {r['skipped_steps']:.0f}, loop overruns "
              f"{r['overruns']:.0f}, handler up to "
              f"{r['handler_max_ms']:.1f} ms; notes {r['notes']:.0f}: played {r['played']:.0f}, late "
              f"{r['late']:.0f} (plans ready late {r['replanned_late']:.0f}); {planning(mode, r['ms_per_note'])}",
              flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
