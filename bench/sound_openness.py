"""What a pedal controller streaming /batteur/sound/openness costs the sound node's render thread.

    python bench/sound_openness.py            # about 10 s; pin it to one core (taskset -c N) for steady figures

Measured in one run, on the shipped kit's modal hi-hat (506 modes):

1. One openness change: a full rebuild of the hat (what every message cost before: plate modes and tables), the
   exact retune a stroke's or the plates' openness now takes (the tables recomputed, the modes kept), and the
   derived retune a message now takes (the tables derived from the last full build by real factors).
2. A stream, wall time over audio time of handle + step (over 1: the node cannot keep real time): no messages,
   one message a block and 8 a block (a slider dragged), the way before (each message rebuilt the hat at once)
   and now (the latest of a block's messages applied once, at the block's start).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from dataclasses import replace  # noqa: E402

from common.kit import load_kit  # noqa: E402
from common.messages.sound import SoundOpenness  # noqa: E402
from services.sound.core import SoundCore, SoundSettings  # noqa: E402
from services.sound.instruments import HiHat  # noqa: E402

BLOCKS = 375  # 2 s at 48 kHz, 256-sample blocks


def _core() -> SoundCore:
    return SoundCore(SoundSettings(latency=0.0, model="modal", use_pyo=False, record=False,
                                   background_rebuilds=True), load_kit("default", warn=False))


def _pedal(i: int) -> float:
    """A pedal rocking between 0.2 and 0.8 over 60 messages."""
    return 0.2 + 0.6 * abs(((i % 60) - 30) / 30)


def _per_call_ms(f: Callable[[int], None], n: int = 60) -> float:
    t0 = time.perf_counter()
    for i in range(n):
        f(i)
    return (time.perf_counter() - t0) / n * 1e3


def _rebuild_at_once(core: SoundCore, hat: HiHat, value: float) -> None:
    """Before: /batteur/sound/openness applied on arrival by a full rebuild (and the choke of a drop)."""
    old = hat.p.openness
    hat.p = replace(hat.p, openness=value)
    hat.rebuild()
    if value < old:
        hat.choke(old, value, core.pool)


def _stream(core: SoundCore, per_block: int, before: bool) -> float:
    """Wall over audio time of BLOCKS blocks with ``per_block`` openness messages before each."""
    hat = core.instruments.instruments["hihat"]
    assert isinstance(hat, HiHat)
    dt = core.block / core.sample_rate
    t0, a0 = time.perf_counter(), core.now
    for i in range(BLOCKS):
        for j in range(per_block):
            value = _pedal(i * per_block + j)
            if before:
                _rebuild_at_once(core, hat, value)
            else:
                core.handle(SoundOpenness(instrument="hihat", value=value), core.now, "pedal")
        core.step(core.now + dt)
    return (time.perf_counter() - t0) / (core.now - a0)


def main(argv: list[str] | None = None) -> None:
    import argparse

    argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter).parse_args(argv)
    core = _core()
    try:
        core.step(0.1)
        hat = core.instruments.instruments["hihat"]
        assert isinstance(hat, HiHat)
        block_ms = core.block / core.sample_rate * 1e3
        rebuild = _per_call_ms(lambda i: _rebuild_at_once(core, hat, _pedal(i)))
        exact = _per_call_ms(lambda i: hat.retune_openness(_pedal(i)))
        derived = _per_call_ms(lambda i: hat.retune_openness(_pedal(i), derived=True))
        print(f"one openness change, {hat.bank.size} modes (block {block_ms:.2f} ms):")
        print(f"  full rebuild (before, every message)   {rebuild:6.2f} ms")
        print(f"  exact retune (a stroke, the plates)    {exact:6.2f} ms  ({rebuild / exact:.1f}x cheaper)")
        print(f"  derived retune (a message, now)        {derived:6.2f} ms  ({rebuild / derived:.1f}x cheaper)")
        idle = _stream(core, 0, before=False)
        print(f"stream of openness messages, wall / audio time ({BLOCKS} blocks; no messages {idle:.3f}):")
        for per_block in (1, 8):
            was, now = _stream(core, per_block, before=True), _stream(core, per_block, before=False)
            cost_was, cost_now = ((x - idle) * block_ms / per_block for x in (was, now))  # ms per message
            print(f"  {per_block} a block: before {was:.3f}, now {now:.3f}; per message before {cost_was:.2f} ms, "
                  f"now {cost_now:.2f} ms ({cost_was / max(cost_now, 1e-9):.1f}x less)")
    finally:
        core.close()


if __name__ == "__main__":
    main()
