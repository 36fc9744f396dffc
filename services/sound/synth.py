"""Signal-based drum synthesis: oscillators, noise, filters and envelopes (the analogue drum machine way).

Each instrument kind has a recipe: a kick is a sine whose pitch falls fast
plus a click; a snare two sines plus band-passed noise; a tom a falling
sine; cymbals and hi-hats six detuned square waves (as in the TR-808)
through a high band-pass plus noise; a cowbell two square waves through a
band-pass. Velocity scales the level and opens the filters (brighter).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import signal

from services.sound.voices import F64, Voice, bandpass

METAL_RATIOS = np.array([1.0, 1.4471, 1.6170, 1.9265, 2.5028, 2.6637])
"""The TR-808's six square-wave oscillator ratios (205.3 Hz ... 546.8 Hz)."""


@dataclass(frozen=True)
class Tone:
    """A sine with an exponential pitch glide and an exponential decay."""

    f_start: float
    f_end: float
    glide: float  # pitch glide time constant, s
    amp: float
    decay: float  # s


@dataclass(frozen=True)
class Band:
    """Band-passed noise or metallic squares with an exponential decay."""

    lo: float
    hi: float
    amp: float
    decay: float
    metal_hz: float = 0.0  # 0: white noise; >0: six square waves from this base


@dataclass(frozen=True)
class Recipe:
    tones: tuple[Tone, ...]
    bands: tuple[Band, ...]
    name: str = ""  # its key in SYNTH_TRIM_DB and SYNTH_VELOCITY_EXPONENT

    @property
    def trim(self) -> float:
        """Linear gain that levels it with the modal model (SYNTH_TRIM_DB)."""
        return float(10.0 ** (SYNTH_TRIM_DB.get(self.name, 0.0) / 20.0))

    @property
    def velocity_exponent(self) -> float:
        """Its level grows as (velocity / 3 m/s) to this power (SYNTH_VELOCITY_EXPONENT, else 1.1)."""
        return SYNTH_VELOCITY_EXPONENT.get(self.name, 1.1)


SYNTH_TRIM_DB: dict[str, float] = {
    "kick": -12.9, "snare": -10.8, "snare_rim": -17.0, "snare_rimshot": 2.6, "tom": -12.5, "crash": -7.4,
    "splash": -5.6, "china": -7.0, "ride": -4.1, "cymbal": -5.8, "cymbal_bell": -0.7, "cowbell": -9.8,
}
"""Level of each recipe relative to its design, dB, so that a strike sounds as loud as the same strike of the modal
model (the default, whose level is calibrated): the mean difference of their RMS over the first 200 ms, measured on
the default kit at its strike points, 0.5-6 m/s (tests/sound/test_sound_model_levels.py checks 1.5 dB). Kick,
china, ride and ride bell moved with the modal model when its contact came to give the kit's restitution (-1.4,
-0.6, -0.4, -0.7 dB); the hi-hat's follow another velocity law (left: docs/sound.md, "Sample playback and
signal-based synthesis")."""

SYNTH_VELOCITY_EXPONENT: dict[str, float] = {"crash": 0.95, "splash": 0.95, "china": 0.95, "ride": 0.95, "cymbal": 0.95}
"""Velocity exponents other than 1.1: a metal recipe opens its band with velocity, so its level grows faster than
the gain alone says; a smaller exponent follows the modal model's growth."""


def recipe_for(kind: str, instrument: str, zone: str, size: float, openness: float) -> Recipe:
    """The recipe of one strike.

    Parameters
    ----------
    kind : str
        membrane, cymbal, hihat or bell.
    instrument : str
        Instrument id (kick and snare get their own recipes).
    zone : str
        Zone struck (rim, bell, pedal, ...).
    size : float
        Radius, metres (sets the pitch of drums and cymbals).
    openness : float
        Hi-hat openness in [0, 1].
    """
    if kind == "membrane":
        if zone in ("rim", "rimshot") and "snare" in instrument:  # a rimshot is as loud as a head stroke: its own trim
            return Recipe((Tone(1700, 1700, 1.0, 0.5, 0.02), Tone(520, 480, 0.05, 0.4, 0.05)),
                          (Band(2000, 7000, 0.4, 0.02),), f"snare_{zone}")
        f0 = 0.2 * 343.0 / (2 * size)  # about the pitch of a tuned drum of that size
        if "kick" in instrument or "bass" in instrument:
            return Recipe((Tone(160, 50, 0.035, 1.0, 0.35),), (Band(1500, 6000, 0.15, 0.006),), "kick")
        if "snare" in instrument:
            return Recipe((Tone(330, 185, 0.02, 0.5, 0.12), Tone(480, 330, 0.02, 0.3, 0.07)),
                          (Band(1800, 9000, 0.7, 0.16),), "snare")
        return Recipe((Tone(f0 * 1.6, f0, 0.05, 0.9, 0.45),), (Band(800, 4000, 0.08, 0.02),), "tom")
    if kind == "hihat":
        if zone == "pedal":
            return Recipe((), (Band(5000, 14000, 0.35, 0.03, metal_hz=330),), "hihat_pedal")
        decay = 0.05 + 0.9 * openness**2
        return Recipe((), (Band(6000, 16000, 0.6, decay, metal_hz=330), Band(7000, 15000, 0.25, decay)), "hihat")
    if kind == "cymbal":
        if zone == "bell":
            return Recipe((Tone(750, 750, 1.0, 0.5, 1.5), Tone(1890, 1890, 1.0, 0.25, 1.0)),
                          (Band(3000, 12000, 0.3, 1.0, metal_hz=300),), "cymbal_bell")
        decay = 1.2 + 8.0 * size
        metal = Band(3500, 15000, 0.6, decay, metal_hz=200 + 40 / size)
        name = next((n for n in ("crash", "splash", "china", "ride") if n in instrument), "cymbal")
        return Recipe((), (metal, Band(5000, 16000, 0.3, decay * 0.7)), name)
    # bell (cowbell)
    return Recipe((), (Band(600, 2500, 1.2, 0.25, metal_hz=540 / METAL_RATIOS[1]),), "cowbell")


class SynthVoice(Voice):
    """Renders a :class:`Recipe` scaled by ``gain`` with a velocity-dependent brightness."""

    def __init__(
        self, instrument: str, recipe: Recipe, gain: float, brightness: float, seed: int,
        sample_rate: float = 48000.0, delay: int = 0,
    ) -> None:
        super().__init__(instrument, delay)
        self.recipe = recipe
        self.gain = float(gain)
        self.sr = float(sample_rate)
        self.t = 0
        self.rng = np.random.default_rng(seed)
        self.phase = np.zeros(len(recipe.tones))
        self.metal_phase = [np.zeros(6) for _ in recipe.bands]
        nyq = 0.45 * self.sr
        self.filters = []
        for b in recipe.bands:
            hi = min(b.hi * (0.5 + 0.5 * brightness), nyq)
            lo = min(b.lo, hi * 0.7)
            sos = bandpass(float(lo), float(hi), self.sr)
            self.filters.append([sos, np.zeros((sos.shape[0], 2))])
        self.length = max([t.decay for t in recipe.tones] + [b.decay for b in recipe.bands] + [0.01]) * 7.0  # -60 dB
        self.level = abs(self.gain)

    def synth(self, n: int) -> F64:
        t = (self.t + np.arange(n)) / self.sr
        self.t += n
        y = np.zeros(n)
        for i, tone in enumerate(self.recipe.tones):
            f = tone.f_end + (tone.f_start - tone.f_end) * np.exp(-t / tone.glide)
            ph = self.phase[i] + np.cumsum(2 * np.pi * f / self.sr)
            self.phase[i] = ph[-1] % (2 * np.pi)
            y += tone.amp * np.exp(-t / tone.decay) * np.sin(ph)
        for j, band in enumerate(self.recipe.bands):
            if band.metal_hz > 0:
                # six square waves from phase accumulators in cycles (no sin per sample)
                freqs = band.metal_hz * METAL_RATIOS / self.sr
                ph = self.metal_phase[j][:, None] + np.outer(freqs, np.arange(1, n + 1))
                self.metal_phase[j] = ph[:, -1] % 1.0
                src = (np.count_nonzero((ph % 1.0) < 0.5, axis=0) * (2.0 / 6.0) - 1.0).astype(np.float64)
            else:
                src = self.rng.standard_normal(n)
            sos, zi = self.filters[j]
            filtered, self.filters[j][1] = signal.sosfilt(sos, src, zi=zi)
            y += band.amp * np.exp(-t / band.decay) * filtered * 2.0
        if t[-1] > self.length:
            self._finished = True
        self.level = abs(self.gain) * float(np.exp(-t[-1] / (self.length / 7.0)))
        return y * self.gain
