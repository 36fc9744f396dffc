"""Strikes land on their sample over long runs at each supported rate: the sample clock is a counter, not a sum of
block periods (256 samples at 44.1 kHz is no exact float number of seconds)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
from sound_helpers import impact, one_drum_kit

from services.sound.core import SoundCore, SoundSettings

RUN_S = 600.0
LATENCY_S = 0.05
ONSET = 1e-4
"""A strike's first sample is above this (a medium strike peaks near 0.2); before it the block is silent but for
rounding residue of the strike folded into the bank at the block's start (about 1e-9)."""


def _strike_times(base: float) -> list[float]:
    """Rig times of strikes every 30 s over the run, each at another fraction of a sample and place in its block."""
    return [base + 30.0 * k + 0.0123457 * k for k in range(1, int(RUN_S / 30.0))]


def _onsets(core: SoundCore, expected: list[int], advance: Callable[[], tuple[int, np.ndarray]]) -> list[int]:
    """Render block by block (``advance()`` renders the next stretch and returns its first sample and audio) and
    return the first sample above ONSET near each expected onset."""
    found: list[int] = []
    end = int((RUN_S + 1.0) * core.sample_rate)
    while core.next_sample < end and len(found) < len(expected):
        start, audio = advance()
        if audio.size and start + audio.shape[0] > expected[len(found)] - 4 * core.block:
            loud = np.nonzero(np.abs(audio) > ONSET)[0]
            if loud.size:
                found.append(start + int(loud[0]))
    return found


@pytest.mark.slow
@pytest.mark.parametrize(("rate", "block"), [(44100, 64), (48000, 256), (96000, 512)])
def test_offline_strikes_land_on_their_sample_after_ten_minutes(rate: int, block: int) -> None:
    core = SoundCore(SoundSettings(sample_rate=rate, block_size=block, latency=LATENCY_S, record=False),
                     one_drum_kit())
    try:
        times = _strike_times(0.0)
        for seq, t in enumerate(times):
            core.handle(impact(seq, t), 0.0, "test")

        def advance() -> tuple[int, np.ndarray]:
            start = core.next_sample
            return start, core.render_block()

        expected = [round((t + LATENCY_S) * rate) for t in times]
        assert _onsets(core, expected, advance) == expected
    finally:
        core.close()


@pytest.mark.slow
def test_live_strikes_land_on_the_rig_clock_after_ten_minutes() -> None:
    """As the node runs: the sample clock starts at the first step, a day into the rig's time; steps come on the
    node's absolute deadlines and impacts a few milliseconds before their time."""
    rate, block = 44100, 128
    ahead_s = 2 * block / rate + 0.002
    core = SoundCore(SoundSettings(sample_rate=rate, block_size=block, latency=LATENCY_S, record=False, origin=None,
                                   render_ahead=ahead_s), one_drum_kit())
    try:
        base = 86400.123
        core.step(base)
        times = _strike_times(base)
        pending = list(enumerate(times))
        tick = [0]
        blocks: list[np.ndarray] = []
        core.on_block = blocks.append

        def advance() -> tuple[int, np.ndarray]:
            tick[0] += 1
            now = base + tick[0] * block / rate
            while pending and pending[0][1] - 0.003 <= now:
                seq, t = pending.pop(0)
                core.handle(impact(seq, t), now, "interaction")
            start = core.next_sample
            blocks.clear()
            core.step(now)
            return start, (np.concatenate(blocks) if blocks else np.zeros(0, dtype=np.float32))

        expected = [round((t + LATENCY_S - base) * rate) for t in times]
        assert _onsets(core, expected, advance) == expected
        assert core.late == 0
    finally:
        core.close()
