"""Snare wires follow the head's damping: the head drives them, so a damped head silences its wires too."""

from __future__ import annotations

import time

import numpy as np
from scipy import signal
from sound_helpers import SR, impact, one_drum_kit

from common.messages.sound import SoundDamping, SoundSnares
from services.sound.core import SoundCore, SoundSettings
from services.sound.voices import NoiseVoice

DAMPED = SoundDamping(instrument="drum", sigma0=300.0, sigma1=0.0)  # a hand on the head: T60 23 ms
WIRE_BAND_HZ = (2500.0, 8000.0)  # where the wires' buzz is, above the head's strong low modes


def _core(snares: float, background: bool = False) -> SoundCore:
    core = SoundCore(SoundSettings(latency=0.01, use_pyo=False, background_rebuilds=background), one_drum_kit())
    core.handle(SoundSnares(instrument="drum", value=snares), 0.0, "panel")
    return core


def _band_energy(x: np.ndarray) -> float:
    sos = signal.butter(4, WIRE_BAND_HZ, btype="bandpass", fs=SR, output="sos")
    return float(np.sum(signal.sosfilt(sos, x.astype(np.float64)) ** 2))


def _render(snares: float, damping_at: float | None, until: float = 0.4, strike_at: float = 0.0) -> np.ndarray:
    """A strike at rig time ``strike_at`` on a drum with wires at ``snares``; the head damped at rig time
    ``damping_at`` (seconds; None: never)."""
    core = _core(snares)
    try:
        if damping_at is not None and damping_at <= 0.0:
            core.handle(DAMPED, 0.0, "panel")
        core.handle(impact(1, strike_at), 0.0, "test")
        if damping_at is not None and damping_at > 0.0:
            core.render(damping_at)
            core.handle(DAMPED, core.now, "panel")
        core.render(until)
        return core.recording()
    finally:
        core.close()


def _wires(damping_at: float | None) -> np.ndarray:
    """What the snare wires add to the drum: the render with them minus the one without (same strike)."""
    return _render(1.0, damping_at) - _render(0.0, damping_at)


def test_damping_the_head_silences_its_ringing_wires() -> None:
    after = slice(int(0.15 * SR), int(0.4 * SR))  # from 50 ms after the damping
    free, damped = _wires(None), _wires(0.1)
    before = int(0.1 * SR) // 256 * 256  # the blocks rendered before the damping arrived
    assert np.array_equal(free[:before], damped[:before])  # the same buzz until the hand lands
    assert _band_energy(free[after]) > 0.0
    assert _band_energy(damped[after]) < 1e-4 * _band_energy(free[after])


def test_wires_on_an_already_damped_head_are_short() -> None:
    window = slice(int(0.06 * SR), int(0.3 * SR))  # from 50 ms after the strike
    free, damped = _wires(None), _wires(0.0)
    assert _band_energy(damped[window]) < 1e-4 * _band_energy(free[window])


def _settle(core: SoundCore) -> None:
    """Step the core, as the node does, until its background change is swapped in."""
    deadline = time.monotonic() + 120.0
    while core.rebuilding:
        assert time.monotonic() < deadline, "the background change never finished"
        core.step(core.now + 0.001)
        time.sleep(0.002)


def test_wires_follow_a_damping_applied_in_the_background() -> None:
    """The live node computes the change on a copy of the drum and swaps it in: the ringing wires follow too."""
    live = _core(1.0, background=True)
    try:
        _settle(live)  # the wires on
        struck = live.now
        live.handle(impact(1, struck), struck, "test")
        live.render(struck + 0.05)
        live.handle(DAMPED, live.now, "panel")
        _settle(live)
        start = live.now
        live.render(start + 0.1)
        audio = live.recording()
    finally:
        live.close()
    # the wires alone, undamped
    free = _render(1.0, None, start + 0.1, struck) - _render(0.0, None, start + 0.1, struck)
    window = slice(int((start + 0.02) * SR), int((start + 0.1) * SR))
    assert _band_energy(free[window]) > 0.0
    # the damped head is silent by then: what the live drum still sounds in the band would be its wires
    assert _band_energy(audio[window]) < 1e-3 * _band_energy(free[window])


def test_a_new_decay_starts_on_the_next_sample_even_inside_a_synthesised_chunk() -> None:
    """Noise voices synthesise 2,048 samples ahead; a damping between blocks must not wait for the next chunk."""
    block, changed_at = 256, 10 * 256  # not a multiple of the chunk

    def voice() -> NoiseVoice:
        return NoiseVoice("snare", (1800.0, 9000.0), 0.1, 0.002, 0.09, seed=7, sample_rate=SR)

    free, damped = voice(), voice()
    a, b = np.zeros(20 * block, dtype=np.float32), np.zeros(20 * block, dtype=np.float32)
    for k in range(20):
        if k * block == changed_at:
            damped.set_decay(0.01)
        free.render(a[k * block:(k + 1) * block])
        damped.render(b[k * block:(k + 1) * block])
    assert np.array_equal(a[:changed_at], b[:changed_at])
    s = np.arange(20 * block - changed_at) / SR  # seconds since the change
    expected = a[changed_at:] * np.exp(-s * (1 / 0.01 - 1 / 0.09))
    assert np.allclose(b[changed_at:], expected, rtol=1e-5, atol=1e-9)
