"""Cymbals and bells: the ride's bell zone, plate mode density, cowbell partials."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from sound_helpers import impact, peak_near, spectrum

from services.sound.core import SoundCore, SoundSettings
from services.sound.instruments import Cymbal
from services.sound.plates import COWBELL_RATIOS, plate_modes


def render(instrument: str, zone: str, r: float, seconds: float = 1.0) -> tuple[np.ndarray, SoundCore]:
    core = SoundCore(SoundSettings(latency=0.0, use_pyo=False))
    core.handle(impact(1, 0.0, instrument, zone=zone, r=r, velocity=4.0), 0.0, "t")
    audio = core.render(seconds)
    core.close()
    return audio, core


def test_ride_bell_zone_rings_the_bell_partials() -> None:
    bell, core = render("ride", "bell", 0.1)
    bow, _ = render("ride", "bow", 0.6)
    ride = core.instruments.instruments["ride"]
    assert isinstance(ride, Cymbal)
    f_bell = ride.p.bell_hz
    fb, mb = spectrum(bell[4800:])
    fw, mw = spectrum(bow[4800:])
    _, bell_peak = peak_near(fb, mb, f_bell, rel=0.01)
    _, bow_peak = peak_near(fw, mw, f_bell, rel=0.01)
    assert 20 * np.log10(bell_peak / bow_peak) > 12.0
    # and the bell partial stands out of the bell strike's spectrum around it
    band = (fb > 0.8 * f_bell) & (fb < 1.2 * f_bell)
    assert bell_peak >= 0.99 * np.max(mb[band])


def test_plate_modes_are_dense_and_uniform_in_frequency() -> None:
    modes = plate_modes(0.203, 0.0012, 100000)
    f = modes.freq
    assert 500 < f.shape[0] < 2000  # a 16" crash: hundreds of modes below 20 kHz
    counts, _ = np.histogram(f, bins=[2000, 6000, 10000, 14000, 18000])
    assert counts.min() > 0.6 * counts.max()  # constant modal density, as plate theory predicts


def test_the_docs_give_the_mode_counts_the_code_builds() -> None:
    """docs/sound.md's plate mode counts per default cymbal (they said 700 to 830, the splash has under 400)
    and its largest mode set of the default kit, as the code builds them."""
    text = " ".join((Path(__file__).resolve().parents[2] / "docs" / "sound.md").read_text().split())
    core = SoundCore(SoundSettings(latency=0.0, use_pyo=False))
    try:
        instruments = dict(core.instruments.instruments)
    finally:
        core.close()
    cymbals = {name: inst for name, inst in instruments.items() if isinstance(inst, Cymbal)}
    assert {"splash", "hihat", "ride", "crash", "china"} <= set(cymbals)
    counts = ", ".join(f"{name.replace('hihat', 'hi-hat')} {cymbals[name].n_plate:,}"
                       + (f" (plus {cymbals[name].bank.size - cymbals[name].n_plate} bell partials)"
                          if cymbals[name].bank.size > cymbals[name].n_plate else "")
                       for name in sorted(cymbals, key=lambda n: cymbals[n].n_plate))
    assert f"plates have {counts} modes" in text
    largest = max(instruments.values(), key=lambda inst: inst.bank.size)
    assert isinstance(largest, Cymbal)
    assert f"the default kit has at most {largest.bank.size:,}, a cymbal" in text
    assert f"on a default cymbal ({largest.bank.size:,})" in text


def test_cowbell_partials_are_where_the_model_puts_them() -> None:
    audio, core = render("cowbell", "centre", 0.5, seconds=0.6)
    bell = core.instruments.instruments["cowbell"]
    f0 = float(bell.bank.freq[0])
    freqs, mag = spectrum(audio[480:])
    for ratio in COWBELL_RATIOS[:4]:
        measured, _ = peak_near(freqs, mag, f0 * ratio, rel=0.01)
        assert abs(measured / (f0 * ratio) - 1) < 0.005
