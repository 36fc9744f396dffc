"""Real-time factor of the physics core at a 1 kHz step (goal: >= 5x real time on one core).

    python bench/physics_rtf.py            # about 15 s
    python bench/physics_rtf.py --seconds 3 --repeat 3   # best of 3 runs per case (a shared machine)

Measures simulated seconds per wall-clock second for the strike scene and for
the full 57-DOF drummer with the whole kit, idle (holding the rest posture)
and playing strokes (left hand on the snare, right hand on the hi-hat, kick),
in each control mode, with full control updates at every step (1 kHz, the default), at 500 Hz
and at 250 Hz (the PD corrects the held torques at every step between), and PyBullet's step alone.
Timing on a shared machine is noisy: compare ratios from one run.
"""

from __future__ import annotations

import argparse
import cProfile
import math
import pstats
import time
from collections.abc import Callable, Sequence

import numpy as np

from common.arg_types import count, seconds
from common.kit import EventType, Kit
from services.physics.core import PhysicsCore
from services.physics.drummer import DrummerScene
from services.physics.strokes import strokes_knots


def hit_point(kit: Kit, event: EventType) -> tuple[np.ndarray, np.ndarray]:
    spec = kit.events[event]
    obj = kit.object(spec.object)
    r = spec.r * obj.radius
    return np.array(obj.to_world((r * math.cos(spec.theta), r * math.sin(spec.theta), 0.0))), np.array(obj.normal())


def add_groove(core: PhysicsCore, seconds: float) -> None:
    """Eighth notes on the hi-hat, snare on 2 and 4, kick on 1 and 3, at 100 bpm."""
    scene = core.scene
    assert isinstance(scene, DrummerScene)
    beat = 0.6
    for limb, event, times in (
        ("right_hand", EventType.HIHATCLOSED, np.arange(0.3, seconds - 0.2, beat / 2)),
        ("left_hand", EventType.SNARE, np.arange(0.3 + beat, seconds - 0.2, 2 * beat)),
    ):
        hit, normal = hit_point(core.kit, event)
        ts, ps, vs = strokes_knots(scene.rest_targets[limb], hit, normal, list(times), [2.0] * len(times),
                                   lift_s=0.1, return_s=0.12)
        for k in range(len(ts)):
            scene.add_cartesian(limb, float(ts[k]), ps[k], vs[k], 0.0)
    rest = scene.rest_targets["right_foot"]
    down = rest - np.array([0.0, 0.0, 0.05])
    for t in np.arange(0.3, seconds - 0.2, 2 * beat):
        for dt, pos in ((-0.1, rest), (0.0, down), (0.12, rest)):
            scene.add_cartesian("right_foot", float(t + dt), pos, np.zeros(3), 0.0)


def run(core: PhysicsCore, seconds: float) -> tuple[float, int]:
    steps = round(seconds * core.rate_hz)
    start = time.perf_counter()
    contacts = 0
    for k in range(1, steps + 1):
        for out in core.step(k / core.rate_hz):
            contacts += out.to == "interaction"
    return seconds / (time.perf_counter() - start), contacts


def best_of(repeat: int, make: Callable[[], PhysicsCore], seconds: float) -> tuple[float, int]:
    """The highest real-time factor of ``repeat`` fresh runs (the least disturbed by other jobs) and its contacts."""
    best = (0.0, 0)
    for _ in range(repeat):
        core = make()
        result = run(core, seconds)
        core.close()
        best = max(best, result)
    return best


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=seconds, default=2.0,
                        help="simulated seconds per case, at least 0.001 (one step; default 2)")
    parser.add_argument("--repeat", type=count, default=1, help="runs per case, the best is printed (default 1)")
    parser.add_argument("--profile", action="store_true", help="print the top functions of a drummer run")
    return parser


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    parser = build_parser()
    args = parser.parse_args(argv)
    if round(args.seconds * 1000) < 1:  # no step to time: a division by zero after the whole run
        parser.error(f"--seconds {args.seconds:g}: at least 0.001 (one 1 ms step)")
    return args


def main(argv: Sequence[str] | None = None) -> None:
    args = parse_args(argv)

    print(f"physics real-time factor at 1 kHz, {args.seconds:g} simulated s per case (goal >= 5x)")
    t0 = time.perf_counter()
    rtf, contacts = best_of(args.repeat, lambda: PhysicsCore(
        scene="strike", strikes=[(0.1 + 0.25 * k, 3.0) for k in range(int(args.seconds * 4))]), args.seconds)
    print(f"  strike scene (stick + snare)            {rtf:7.2f}x   contacts {contacts}")
    build = time.perf_counter()
    PhysicsCore(scene="drummer").close()
    print(f"  drummer + kit build: {time.perf_counter() - build:.2f} s (limits, rest posture IK, gains)")
    rtf, contacts = best_of(args.repeat, lambda: PhysicsCore(scene="drummer"), args.seconds)
    print(f"  drummer idle, cartesian                 {rtf:7.2f}x   contacts {contacts}")
    for mode, control_hz in (("cartesian", 1000.0), ("cartesian", 500.0), ("cartesian", 250.0), ("joint_pd", 1000.0)):
        def groove(mode: str = mode, control_hz: float = control_hz) -> PhysicsCore:
            core = PhysicsCore(scene="drummer", control=mode, control_rate_hz=control_hz)
            add_groove(core, args.seconds)
            return core

        rtf, contacts = best_of(args.repeat, groove, args.seconds)
        print(f"  drummer groove, {mode:<10} control {control_hz:5.0f} Hz {rtf:7.2f}x   contacts {contacts}")
    # PyBullet's own step while the drummer plays the groove (the rest of the time is the Python control loop)
    core = PhysicsCore(scene="drummer", control="cartesian", control_rate_hz=250.0)
    add_groove(core, args.seconds)
    world = core.world
    step_time = 0.0
    original = world.step

    def timed_step() -> None:
        nonlocal step_time
        t = time.perf_counter()
        original()
        step_time += time.perf_counter() - t

    world.step = timed_step  # type: ignore[method-assign]
    rtf, _ = run(core, args.seconds)
    step_only = step_time / round(args.seconds * core.rate_hz)
    print(f"  PyBullet stepSimulation alone, drummer + kit playing: {1000 * step_only:.3f} ms/step "
          f"= {0.001 / step_only:.2f}x at 1 kHz (of that run's {rtf:.2f}x at 250 Hz control)")
    if args.profile:
        core = PhysicsCore(scene="drummer")
        add_groove(core, 1.0)
        prof = cProfile.Profile()
        prof.enable()
        run(core, 1.0)
        prof.disable()
        pstats.Stats(prof).sort_stats("tottime").print_stats(12)
    print(f"total bench time {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
