"""Rendered membrane audio against the Bessel-zero theory (offline pyo server)."""

from __future__ import annotations

import numpy as np
from scipy.special import jn_zeros
from sound_helpers import SR, impact, peak_near, spectrum

from common.messages.sound import SoundAirLoading, SoundDamping, SoundSecondHead, SoundSnares, SoundTension
from services.sound.core import SoundCore

# (m, n) of the first six distinct membrane modes, in frequency order
FIRST_SIX = [(0, 1), (1, 1), (2, 1), (0, 2), (3, 1), (1, 2)]


def ideal(core: SoundCore) -> None:
    """No air loading, no orientation splitting, light damping, no snare wires: the textbook membrane."""
    inst = core.instruments.instruments["drum"]
    inst.p.splitting = 0.0  # orientation splitting has no message: a property of the head, not a knob
    core.handle(SoundAirLoading(instrument="drum", value=0.0), 0.0, "test")
    core.handle(SoundSecondHead(instrument="drum", gain=0.0, ratio=1.0), 0.0, "test")
    core.handle(SoundDamping(instrument="drum", sigma0=3.0, sigma1=0.0), 0.0, "test")
    core.handle(SoundSnares(instrument="drum", value=0.0), 0.0, "test")


def predicted(core: SoundCore) -> list[float]:
    p = core.instruments.instruments["drum"].p
    c = np.sqrt(p.tension / p.density)
    return [float(jn_zeros(m, n)[-1] / (2 * np.pi * p.radius) * c) for m, n in FIRST_SIX]


def strike_and_render(core: SoundCore, r: float, theta: float = 0.7, seconds: float = 1.5) -> np.ndarray:
    core.handle(impact(1, 0.0, r=r, theta=theta), 0.0, "test")
    audio = core.render(seconds)
    return audio[int(0.02 * SR):]  # skip the contact itself


def test_peaks_match_bessel_prediction_within_half_a_percent(drum_core: SoundCore) -> None:
    ideal(drum_core)
    freqs, mag = spectrum(strike_and_render(drum_core, r=0.55))
    for (m, n), f in zip(FIRST_SIX, predicted(drum_core), strict=True):
        measured, _ = peak_near(freqs, mag, f)
        assert abs(measured - f) / f < 0.005, f"mode ({m},{n}): {measured:.2f} Hz vs Bessel {f:.2f} Hz"


def test_centre_strike_leaves_asymmetric_modes_40_db_down(drum_core: SoundCore) -> None:
    ideal(drum_core)
    f = predicted(drum_core)
    freqs, mag = spectrum(strike_and_render(drum_core, r=0.0))
    _, ref = peak_near(freqs, mag, f[0])
    for (m, _n), fm in zip(FIRST_SIX, f, strict=True):
        if m == 0:
            continue
        _, level = peak_near(freqs, mag, fm, rel=0.005)
        assert 20 * np.log10(level / ref) < -40.0, f"m={m} mode only {20 * np.log10(level / ref):.1f} dB down"


def test_off_centre_strike_excites_asymmetric_modes(drum_core: SoundCore) -> None:
    ideal(drum_core)
    f = predicted(drum_core)
    freqs, mag = spectrum(strike_and_render(drum_core, r=0.5))
    _, ref = peak_near(freqs, mag, f[0])
    _, m1 = peak_near(freqs, mag, f[1], rel=0.005)
    _, m2 = peak_near(freqs, mag, f[2], rel=0.005)
    assert 20 * np.log10(m1 / ref) > -20.0
    assert 20 * np.log10(m2 / ref) > -25.0


def test_doubling_tension_raises_every_mode_by_sqrt2(drum_core: SoundCore) -> None:
    ideal(drum_core)
    f = predicted(drum_core)
    freqs, mag = spectrum(strike_and_render(drum_core, r=0.55))
    before = [peak_near(freqs, mag, fm)[0] for fm in f]
    tension = drum_core.instruments.instruments["drum"].p.tension
    drum_core.handle(SoundTension(instrument="drum", value=2 * tension), drum_core.now, "test")
    drum_core.handle(impact(2, drum_core.now, r=0.55, theta=0.7), drum_core.now, "test")
    start = drum_core.next_sample
    drum_core.render(drum_core.now + 1.5)
    # the first strike has decayed by 1.5 s * 3 /s (39 dB): the second dominates
    audio = drum_core.recording()[start + int(0.05 * SR):]
    freqs2, mag2 = spectrum(audio)
    for fb, fm in zip(before, f, strict=True):
        after, _ = peak_near(freqs2, mag2, fm * np.sqrt(2))
        assert abs(after / fb - np.sqrt(2)) / np.sqrt(2) < 0.005, f"{fb:.1f} -> {after:.1f} Hz"


def test_air_loading_lowers_the_low_modes_most(drum_core: SoundCore) -> None:
    """The physical correction: air mass on the head pulls (0,1) down more than the higher modes."""
    inst = drum_core.instruments.instruments["drum"]
    drum_core.handle(SoundAirLoading(instrument="drum", value=0.0), 0.0, "test")
    ideal_f = inst.bank.freq.copy()
    drum_core.handle(SoundAirLoading(instrument="drum", value=1.0), 0.0, "test")
    loaded = inst.bank.freq
    ratio = loaded[:6] / ideal_f[:6]
    assert np.all(ratio < 1.0)
    assert ratio[0] < ratio[5]  # (0,1) lowered most


def test_second_head_adds_its_own_tuned_modes(drum_core: SoundCore) -> None:
    ideal(drum_core)
    f01 = predicted(drum_core)[0]
    freqs, mag = spectrum(strike_and_render(drum_core, r=0.3))
    _, without = peak_near(freqs, mag, 1.2 * f01, rel=0.005)
    _, ref = peak_near(freqs, mag, f01)
    core2 = SoundCore(drum_core.settings, drum_core.kit)
    try:
        ideal(core2)
        core2.handle(SoundSecondHead(instrument="drum", gain=1.0, ratio=1.2), 0.0, "test")
        freqs2, mag2 = spectrum(strike_and_render(core2, r=0.3))
    finally:
        core2.close()
    measured, with_head = peak_near(freqs2, mag2, 1.2 * f01, rel=0.01)
    assert abs(measured / (1.2 * f01) - 1) < 0.005
    assert 20 * np.log10(with_head / ref) > -30.0
    assert 20 * np.log10(without / ref) < -50.0
