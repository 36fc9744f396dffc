"""Helpers for the sound tests: one-drum kits, impacts, spectra."""

from __future__ import annotations

import time

import numpy as np

from common.core import Outgoing
from common.kit import Kit, KitObject
from common.messages import Impact
from services.sound.core import SoundCore

SR = 48000


def impact(seq: int, t: float, instrument: str = "drum", *, velocity: float = 3.0, r: float = 0.4,
           theta: float = 0.3, zone: str = "centre", impulse: float = 0.0) -> Impact:
    return Impact(seq=seq, time=t, instrument=instrument, zone=zone, r=r, theta=theta, velocity=velocity,
                  impulse=impulse, peak_force=0.0, duration=0.003, part="right_stick_tip")


def one_drum_kit(radius: float = 0.178) -> Kit:
    drum = KitObject(id="drum", kind="membrane", position=(0.0, 0.5, 0.6), radius=radius, depth=0.14)
    return Kit(name="one-drum", objects=[drum], events={})


def spectrum(x: np.ndarray, sr: int = SR, pad: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """Magnitude spectrum (Hann window, zero padded) and its frequencies, Hz."""
    n = x.shape[0]
    w = np.hanning(n)
    mag = np.abs(np.fft.rfft(x * w, n * pad))
    return np.fft.rfftfreq(n * pad, 1.0 / sr), mag


def peak_near(freqs: np.ndarray, mag: np.ndarray, f: float, rel: float = 0.02) -> tuple[float, float]:
    """(frequency, magnitude) of the largest bin within +-rel of f, refined by parabolic interpolation."""
    sel = np.nonzero((freqs > f * (1 - rel)) & (freqs < f * (1 + rel)))[0]
    i = sel[np.argmax(mag[sel])]
    a, b, c = np.log(mag[i - 1] + 1e-30), np.log(mag[i] + 1e-30), np.log(mag[i + 1] + 1e-30)
    delta = 0.5 * (a - c) / (a - 2 * b + c) if (a - 2 * b + c) != 0 else 0.0
    return float(freqs[i] + delta * (freqs[1] - freqs[0])), float(mag[i])


def settle(core: SoundCore) -> list[Outgoing]:
    """Step the core (as the node does) until its background changes are in; the replies it sent meanwhile."""
    out: list[Outgoing] = []
    deadline = time.monotonic() + 120.0
    while core.rebuilding:
        assert time.monotonic() < deadline, "a background change never finished"
        out += core.step(core.now + 0.001)
        time.sleep(0.002)
    return out + core.step(core.now + 0.001)
