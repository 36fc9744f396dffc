"""How many sounding modes the sound service sustains in real time: vectorised bank vs one pyo object per mode.

    python bench/sound_modes.py            # 50,000 modes, 256-sample blocks at 48 kHz (a few seconds)
    python bench/sound_modes.py --modes 20000 --pyo-modes 1000 --blocks 200

Both are measured in the same run on one core (BLAS limited to one thread).
The vectorised bank (services/sound/modal_bank.py) renders every mode of a
block with one matrix product; the pyo baseline is one ``ComplexRes``
resonator object per mode in a manual-mode server. Prints per-block compute
times (median, p99) against the real-time budget, the cost per mode-sample of
each, the modes each sustains at p99 < half a block, and their ratio. Timing
is noisy on a shared machine: compare the two numbers of one run.
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

from common.arg_types import count  # noqa: E402
from services.sound.core import SoundSettings  # noqa: E402
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


BLOCK_SIZES: tuple[int, ...] = get_args(SoundSettings.model_fields["block_size"].annotation)
"""The sound service's block sizes (any other, with a large prime factor, needs a table of modes x block)."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--modes", type=count, default=50000, help="modes in the vectorised bank (default 50000)")
    parser.add_argument("--pyo-modes", type=count, default=2000, help="pyo resonator objects (default 2000)")
    parser.add_argument("--block", type=int, default=256, choices=BLOCK_SIZES,
                        help="block size, samples, as the sound service offers (default 256)")
    parser.add_argument("--blocks", type=count, default=300, help="blocks timed (default 300)")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    sr = 48000
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
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
