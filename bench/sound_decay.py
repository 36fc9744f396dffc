"""CPU per block while the full kit sounds vs after a long decay (the denormal check).

    python bench/sound_decay.py            # about 20 s, no options

Strikes every instrument of the default kit, times blocks while everything
rings, renders a long silence and times blocks again. Resonators that decay
towards zero reach denormal floats and can cost up to 55x more per sample
(ARCHITECTURE.md); the bank zeroes modes below -140 dB and skips silent
instruments, so the decayed kit should cost almost nothing. For contrast the
same bank is also timed with that floor disabled after the same decay, and a
pyo resonator bank with and without ``Denorm`` in front.
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
from services.sound.modal_bank import ModeSet  # noqa: E402
from services.sound.pyo_stage import _quiet_stderr, import_pyo  # noqa: E402

KIT = ["kick", "snare", "hightom", "midtom", "floortom", "hihat", "crash", "splash", "ride", "china", "cowbell"]


def block_cpu(core: SoundCore, blocks: int) -> np.ndarray:
    times = []
    for _ in range(blocks):
        c0 = time.thread_time()
        core.render_block()
        times.append(time.thread_time() - c0)
    return np.asarray(times)


def bank_after_decay(floor: float, seconds: float = 60.0, modes: int = 5000) -> tuple[float, float]:
    """(CPU ms per block while sounding, after ``seconds`` of decay) for a bank with the given floor."""
    bank = ModeSet(48000, 256, floor=floor)
    rng = np.random.default_rng(1)
    f = rng.uniform(50, 15000, modes)
    bank.set_modes(np.sort(f), np.full(modes, 3.0))
    bank.strike(np.full(modes, 0.01 + 0j))
    out = np.zeros(256, dtype=np.float32)

    def timed(n: int) -> float:
        c0 = time.thread_time()
        for _ in range(n):
            bank.process(out)
        return (time.thread_time() - c0) / n * 1e3

    sounding = timed(100)
    for _ in range(int(seconds * 48000 / 256)):
        bank.process(out)
    return sounding, timed(100)


def pyo_after_decay(denorm: bool, seconds: float = 30.0, modes: int = 500) -> tuple[float, float]:
    """(CPU ms per block while sounding, after decay) of pyo resonators struck once."""
    pyo = import_pyo()
    with _quiet_stderr():
        server = pyo.Server(sr=48000, nchnls=1, buffersize=256, duplex=0, audio="manual").boot()
    server.setServer()
    server.start()
    try:
        trig = pyo.Trig()
        src = pyo.TrigEnv(trig, pyo.LinTable([(0, 1.0), (8, 0.0)], size=8), dur=8 / 48000)
        src_in = pyo.Denorm(src) if denorm else src
        res = [pyo.Biquad(src_in, freq=float(f), q=200.0, type=2) for f in np.linspace(100, 12000, modes)]
        mix = pyo.Mix(res, voices=1)
        fill = pyo.TableFill(mix, pyo.DataTable(size=256))
        trig.play()

        def timed(n: int) -> float:
            c0 = time.thread_time()
            for _ in range(n):
                server.process()
            return (time.thread_time() - c0) / n * 1e3

        sounding = timed(100)
        for _ in range(int(seconds * 48000 / 256)):
            server.process()
        after = timed(100)
        del fill, mix, res, src_in, src, trig
        return sounding, after
    finally:
        server.stop()
        server.shutdown()


def build_parser() -> argparse.ArgumentParser:
    return argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)


def main(argv: Sequence[str] | None = None) -> int:
    build_parser().parse_args(argv)
    core = SoundCore(SoundSettings(latency=0.0, record=False))
    try:
        for i, name in enumerate(KIT):
            core.handle(Impact(seq=i, time=0.0, instrument=name, zone="centre", r=0.5, theta=0.3, velocity=6.0,
                               impulse=0.0, peak_force=0.0, duration=0.002, part="stick"), 0.0, "bench")
        core.render_block()
        modes = core.sounding_modes()
        sounding = block_cpu(core, 200)
        core.render(60.0)
        decayed = block_cpu(core, 200)
    finally:
        core.close()
    print(f"full kit, {modes} modes struck: CPU per 256-sample block while sounding median "
          f"{np.median(sounding) * 1e3:.3f} ms p99 {np.percentile(sounding, 99) * 1e3:.3f} ms")
    print(f"after 60 s of decay ({core.sounding_modes()} modes still sounding): median "
          f"{np.median(decayed) * 1e3:.3f} ms p99 {np.percentile(decayed, 99) * 1e3:.3f} ms "
          f"(ratio decayed/sounding {np.median(decayed) / np.median(sounding):.3f})")
    for floor in (1e-7, 0.0):
        s, a = bank_after_decay(floor)
        label = "floor -140 dB" if floor else "floor disabled"
        print(f"5000-mode bank, {label}: {s:.3f} ms per block sounding, {a:.3f} ms after 60 s ({a / s:.2f}x)")
    for denorm in (True, False):
        s, a = pyo_after_decay(denorm)
        print(f"pyo 500 Biquad resonators {'with' if denorm else 'without'} Denorm: {s:.3f} ms sounding, "
              f"{a:.3f} ms after 30 s ({a / s:.2f}x)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
