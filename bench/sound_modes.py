"""How many sounding modes the sound service sustains in real time: vectorised bank vs one pyo object per mode.

    python bench/sound_modes.py            # 50,000 modes, 256-sample blocks at 48 kHz (a few seconds)
    python bench/sound_modes.py --modes 20000 --pyo-modes 1000 --blocks 200
    python bench/sound_modes.py --change-modes 20000 --blocks 0   # only the /batteur/sound/modes change
    python bench/sound_modes.py --blocks 0 --change-modes 0 --strike-modes 20000   # only the strike cost

Both are measured in the same run on one core (BLAS limited to one thread).
The vectorised bank (services/sound/modal_bank.py) renders every mode of a
block with one matrix product; the pyo baseline is one ``ComplexRes``
resonator object per mode in a manual-mode server. Prints per-block compute
times (median, p99) against the real-time budget, the cost per mode-sample of
each, the modes each sustains at p99 < half a block, and their ratio. Timing
is noisy on a shared machine: compare the two numbers of one run.

Then how long a ``/batteur/sound/modes`` change on the snare blocks the render
loop: applied at once (offline renders; the live node before background
rebuilds), the first change (SciPy's Bessel-zero table) and a later one; and
with ``background_rebuilds`` (the live node): the longest gap between the
loop's steps, paced at the block rate, while the worker computes the change.

Then what a strike on the snare costs the render loop, at its default mode
count and after ``/batteur/sound/modes N``: the time of the block the strike
starts in and of the next one (the contact's later chunks land there), median
over strikes at varied points, against a block without a strike.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # one core, before numpy loads BLAS
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402
from collections.abc import Sequence  # noqa: E402
from typing import get_args  # noqa: E402

import numpy as np  # noqa: E402

from common.arg_types import count, whole, whole_non_negative  # noqa: E402
from common.messages import Impact  # noqa: E402
from common.messages.sound import SoundModes  # noqa: E402
from services.sound import membrane  # noqa: E402
from services.sound.core import SoundCore, SoundSettings  # noqa: E402
from services.sound.modal_bank import ModeSet  # noqa: E402
from services.sound.pyo_stage import _quiet_stderr, import_pyo  # noqa: E402


def bank_block_times(modes: int, block: int, sr: int, blocks: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(wall, thread CPU) seconds per block of a ModeSet with ``modes`` sounding modes (re-struck so none decays)."""
    rng = np.random.default_rng(seed)
    bank = ModeSet(sr, block)
    freq = rng.uniform(40.0, 20000.0, modes)
    bank.set_modes(freq, 0.5 + 1e-7 * freq**2)
    amp = (rng.standard_normal(modes) + 1j * rng.standard_normal(modes)) * 1e-3
    out = np.zeros(block, dtype=np.float32)
    times, cpu = [], []
    for i in range(blocks + 10):
        if i % 50 == 0:
            bank.strike(amp, offset=int(rng.integers(0, block)))
        out[:] = 0.0
        c0, t0 = time.thread_time(), time.perf_counter()
        bank.process(out)
        times.append(time.perf_counter() - t0)
        cpu.append(time.thread_time() - c0)
    return np.asarray(times[10:]), np.asarray(cpu[10:])


def pyo_block_times(modes: int, block: int, sr: int, blocks: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(wall, thread CPU) seconds per block of a pyo server running one ComplexRes object per mode."""
    pyo = import_pyo()
    rng = np.random.default_rng(seed)
    with _quiet_stderr():
        server = pyo.Server(sr=sr, nchnls=1, buffersize=block, duplex=0, audio="manual").boot()
    server.setServer()
    server.start()
    try:
        exc = pyo.Noise(0.001)  # keeps every resonator busy
        freq = rng.uniform(40.0, 20000.0, modes)
        res = [pyo.ComplexRes(exc, freq=float(f), decay=1.0) for f in freq]
        mix = pyo.Mix(res, voices=1)
        fill = pyo.TableFill(mix, pyo.DataTable(size=block))
        times, cpu = [], []
        for _ in range(blocks + 10):
            c0, t0 = time.thread_time(), time.perf_counter()
            server.process()
            times.append(time.perf_counter() - t0)
            cpu.append(time.thread_time() - c0)
        del fill, mix, res, exc
        return np.asarray(times[10:]), np.asarray(cpu[10:])
    finally:
        server.stop()
        server.shutdown()


def _fresh_tables() -> None:
    """Forget the per-process tables, as in a fresh process: the first change computes its Bessel-zero table and
    (over SHAPE_TABLE_MODES modes) its grid of Bessel functions."""
    membrane._TABLES.clear()
    membrane._GRIDS.clear()


def change_blocking(modes: int, block: int, sr: int) -> dict[str, float]:
    """Seconds the render loop is held by a SoundModes change to ``modes`` on the snare (see the docstring)."""
    out: dict[str, float] = {}
    _fresh_tables()
    core = SoundCore(SoundSettings(block_size=block, sample_rate=sr, use_pyo=False, record=False,
                                   origin=None, background_rebuilds=True))
    try:
        period = block / sr
        core.step(0.0)
        for key, value in (("first", modes), ("later", modes - 1)):
            t0 = time.perf_counter()
            core.handle(SoundModes(instrument="snare", value=value), core.now, "bench")
            handled = time.perf_counter()
            worst, steps = handled - t0, 0
            while core.rebuilding or steps == 0:  # step at the block rate, as the node does
                due = handled + steps * period
                time.sleep(max(0.0, due - time.perf_counter()))
                s0 = time.perf_counter()
                core.step(core.now + period)
                worst = max(worst, time.perf_counter() - s0, s0 - due)  # a step's own time, or how late it began
                steps += 1
            out[f"background {key} held"], out[f"background {key} ready"] = worst, time.perf_counter() - t0
        assert core.instruments.instruments["snare"].p.n_modes == modes - 1
    finally:
        core.close()
    _fresh_tables()
    core = SoundCore(SoundSettings(block_size=block, sample_rate=sr, use_pyo=False, record=False))
    try:
        for key, value in (("first", modes), ("later", modes - 1)):
            t0 = time.perf_counter()
            core.handle(SoundModes(instrument="snare", value=value), 0.0, "bench")
            out[f"at once {key}"] = time.perf_counter() - t0
    finally:
        core.close()
    return out


def strike_cost(modes: int, block: int, sr: int, strikes: int = 15) -> dict[str, float]:
    """Median seconds of the render loop's block with a snare strike, of the block after it and of a block
    without one, at the snare's default mode count (keys ``default ...``) and at ``modes`` (``N ...``)."""
    core = SoundCore(SoundSettings(block_size=block, sample_rate=sr, use_pyo=False, record=False, latency=0.0))
    out: dict[str, float] = {}
    rng = np.random.default_rng(1)
    seq = 0
    try:
        for key, value in (("default", 0), ("N", modes)):
            if value:
                core.handle(SoundModes(instrument="snare", value=value), core.now, "bench")  # applied at once
            struck, after, quiet = [], [], []
            for _ in range(strikes + 2):
                seq += 1
                t = core.now + float(rng.uniform(0.0, block / sr))  # somewhere in the next block
                core.handle(Impact(seq=seq, time=t, instrument="snare", zone="centre", r=float(rng.uniform(0.1, 0.9)),
                                   theta=float(rng.uniform(-3.0, 3.0)), velocity=3.0, impulse=0.0, peak_force=0.0,
                                   duration=0.0, part="right_stick_tip"), core.now, "bench")
                times = []
                for _ in range(4):
                    t0 = time.perf_counter()
                    core.render_block()
                    times.append(time.perf_counter() - t0)
                struck.append(times[0])
                after.append(times[1])
                quiet.append(times[3])
            for name, values in (("strike", struck), ("after", after), ("quiet", quiet)):
                out[f"{key} {name}"] = float(np.median(values[2:]))  # the first two warm up
            out[f"{key} modes"] = float(core.instruments.instruments["snare"].bank.size)
    finally:
        core.close()
    return out


BLOCK_SIZES: tuple[int, ...] = get_args(SoundSettings.model_fields["block_size"].annotation)
"""The sound service's block sizes (any other, with a large prime factor, needs a table of modes x block)."""


def _change_modes(text: str) -> int:
    """0 (skip) or a mode count /batteur/sound/modes takes (2..20000: the later change asks one fewer)."""
    value = whole(text)
    if value != 0 and not 2 <= value <= 20000:
        raise argparse.ArgumentTypeError(f"{text!r}: give 0 or 2..20000 (the range of /batteur/sound/modes)")
    return value


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--modes", type=count, default=50000, help="modes in the vectorised bank (default 50000)")
    parser.add_argument("--pyo-modes", type=count, default=2000, help="pyo resonator objects (default 2000)")
    parser.add_argument("--block", type=int, default=256, choices=BLOCK_SIZES,
                        help="block size, samples, as the sound service offers (default 256)")
    parser.add_argument("--blocks", type=whole_non_negative, default=300,
                        help="blocks timed (default 300; 0: skip the bank and pyo timings)")
    parser.add_argument("--change-modes", type=_change_modes, default=20000,
                        help="time a /batteur/sound/modes change to this many modes on the snare (default 20000, "
                        "the most it takes; 0: skip)")
    parser.add_argument("--strike-modes", type=_change_modes, default=20000,
                        help="time the render loop's blocks of a snare strike at its default mode count and at this "
                        "many modes (default 20000; 0: skip)")
    return parser


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.blocks == 0 and args.change_modes == 0 and args.strike_modes == 0:  # was a silent run, exit 0
        parser.error("--blocks 0 --change-modes 0 --strike-modes 0: nothing to time (each 0 skips its part)")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    sr = 48000
    if args.blocks > 0:
        _bank_vs_pyo(args, sr)
    if args.change_modes > 0:
        t = change_blocking(args.change_modes, args.block, sr)
        print(f"/batteur/sound/modes {args.change_modes} on the snare, render loop held "
              f"(block {args.block / sr * 1e3:.2f} ms):")
        print(f"  applied at once (offline): first change {t['at once first']:.3f} s, "
              f"later {t['at once later']:.3f} s")
        for key in ("first", "later"):
            print(f"  in the background (live node), {key} change: loop held at most "
                  f"{t[f'background {key} held'] * 1e3:.1f} ms, new modes playing after "
                  f"{t[f'background {key} ready']:.3f} s")
    if args.strike_modes > 0:
        c = strike_cost(args.strike_modes, args.block, sr)
        print(f"a strike on the snare, render loop's blocks (median; block {args.block / sr * 1e3:.2f} ms):")
        for key, label in (("default", "default modes"), ("N", f"/batteur/sound/modes {args.strike_modes}")):
            print(f"  {label} ({c[f'{key} modes']:.0f} in its bank): block with the strike "
                  f"{c[f'{key} strike'] * 1e3:.2f} ms, the next {c[f'{key} after'] * 1e3:.2f} ms, "
                  f"a block without one {c[f'{key} quiet'] * 1e3:.2f} ms")
    return 0


def _bank_vs_pyo(args: argparse.Namespace, sr: int) -> None:
    budget = args.block / sr
    half = budget / 2

    bank, bank_cpu = bank_block_times(args.modes, args.block, sr, args.blocks)
    pyo_t, pyo_cpu = pyo_block_times(args.pyo_modes, args.block, sr, args.blocks)
    bank_ns = np.median(bank_cpu) / (args.modes * args.block) * 1e9
    pyo_ns = np.median(pyo_cpu) / (args.pyo_modes * args.block) * 1e9

    def line(name: str, modes: int, wall: np.ndarray, cpu: np.ndarray, ns: float) -> None:
        p99w, p99c = float(np.percentile(wall, 99)), float(np.percentile(cpu, 99))
        print(f"{name}, {modes} modes: wall median {np.median(wall) * 1e3:.3f} ms p99 {p99w * 1e3:.3f} ms; "
              f"CPU median {np.median(cpu) * 1e3:.3f} ms p99 {p99c * 1e3:.3f} ms "
              f"({'meets' if p99c < half else 'misses'} the goal on CPU time, "
              f"{'meets' if p99w < half else 'misses'} on wall time); {ns:.3f} ns per mode-sample")

    print(f"block {args.block} samples at {sr} Hz: {budget * 1e3:.3f} ms real time, goal p99 < {half * 1e3:.3f} ms")
    print("(wall time includes preemption by other processes; thread CPU time does not)")
    line("vectorised bank", args.modes, bank, bank_cpu, bank_ns)
    line("pyo ComplexRes objects", args.pyo_modes, pyo_t, pyo_cpu, pyo_ns)
    bank_sustained = int(args.modes * half / float(np.percentile(bank_cpu, 99)))
    pyo_sustained = int(args.pyo_modes * half / float(np.percentile(pyo_cpu, 99)))
    print(f"modes sustainable at CPU p99 < half a block: vectorised {bank_sustained}, pyo objects {pyo_sustained}")
    print(f"ratio (pyo cost / vectorised cost per mode-sample, same run): {pyo_ns / bank_ns:.1f}x")


if __name__ == "__main__":
    raise SystemExit(main())
