"""Render Groove MIDI performances with a recorded kit, then add room, colouring and noise.

Used to make training data (kits in :data:`~services.recogniser.training.kits.TRAIN_KITS`)
and benchmark audio (a kit in ``TEST_KITS``). Audio is generated in memory and never committed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import mido
import numpy as np
from scipy.signal import butter, fftconvolve, lfilter, sosfilt

from services.recogniser.audio import resample
from services.recogniser.classes import class_of_pitch
from services.recogniser.training.kits import KIND_CLASS, PITCH_KIND, RENDER_RATE, Kit


@dataclass(frozen=True)
class Note:
    """One drum note: time in seconds, MIDI pitch and velocity (1..127)."""

    time: float
    pitch: int
    velocity: int


def read_notes(path: str | Path) -> list[Note]:
    """Note-ons of a MIDI file (any channel), times in seconds, sorted."""
    notes: list[Note] = []
    t = 0.0
    for msg in mido.MidiFile(str(path)):
        t += msg.time
        if msg.type == "note_on" and msg.velocity > 0:
            notes.append(Note(t, int(msg.note), int(msg.velocity)))
    return sorted(notes, key=lambda n: n.time)


@dataclass(frozen=True)
class Hit:
    """A rendered hit: onset time (s), class index, MIDI velocity."""

    time: float
    cls: int
    velocity: int


METAL_KINDS = frozenset({"hh_closed", "hh_pedal", "hh_open", "crash", "china", "splash", "ride", "ride_bell"})
"""Cymbal and hi-hat kinds (inharmonic: they take a wider detune and other filter ranges)."""
MIN_DECAY_S = {"hh_open": 0.3, "crash": 0.5, "china": 0.5, "splash": 0.3, "ride": 0.5, "ride_bell": 0.4}
"""Shortest decay time constant a shaped instrument of these kinds may get, s (an open hi-hat or a crash
shortened further would sound like another class)."""


@dataclass
class Variation:
    """A random change of one instrument's sound: resampling (pitch and length), a peaking EQ and a tilt
    (``tilt_db`` more above ``tilt_hz`` than below: first-order low and high pass outputs, which sum to the
    input, weighted by -+ half of it). :meth:`random_wide` adds second-order low and high passes, band-passed
    noise that follows the sample's envelope (snare wires), a shorter decay and a transient gain."""

    factor: float = 1.0
    eq_hz: float = 0.0
    eq_db: float = 0.0
    _cache: dict[int, np.ndarray] = field(default_factory=dict)  # by id() of the kit's (long-lived) layer arrays

    gain: float = 1.0
    curve: float = 1.6
    tilt_hz: float = 1000.0
    tilt_db: float = 0.0
    lowpass_hz: float = 0.0
    highpass_hz: float = 0.0
    noise_db: float | None = None  # wires: band-passed noise this far above the sample's RMS, dB (None: none)
    noise_band: tuple[float, float] = (2000.0, 8000.0)
    noise_decay_s: float = 0.15
    decay_s: float = 0.0  # 0: the sample's own decay; else exp(-(t - decay_hold_s) / decay_s) after a hold
    decay_hold_s: float = 0.01
    attack_db: float = 0.0  # gain of the first milliseconds (1 + a exp(-t / attack_s))
    attack_s: float = 0.005
    seed: int = 0

    @staticmethod
    def random(rng: np.random.Generator) -> Variation:
        return Variation(float(2 ** (rng.uniform(-4, 4) / 12)), float(np.exp(rng.uniform(np.log(80), np.log(8000)))),
                         float(rng.uniform(-9, 9)), gain=float(10 ** (rng.uniform(-12, 10) / 20)),
                         curve=float(rng.uniform(1.0, 2.6)),
                         tilt_hz=float(np.exp(rng.uniform(np.log(300), np.log(5000)))),
                         tilt_db=float(rng.uniform(-8, 8)))

    @staticmethod
    def random_wide(rng: np.random.Generator, kind: str) -> Variation:
        """:meth:`random` and, each with some probability, the further changes (training variety)."""
        v = Variation.random(rng)
        metal = kind in METAL_KINDS

        def logu(lo: float, hi: float) -> float:
            return float(np.exp(rng.uniform(np.log(lo), np.log(hi))))

        if metal and rng.random() < 0.5:  # cymbals: up to 7 semitones
            v.factor = float(2 ** (rng.uniform(-7, 7) / 12))
        if rng.random() < 0.4:
            v.lowpass_hz = logu(2500, 14000) if metal else logu(1200, 12000)
        if rng.random() < 0.25:
            v.highpass_hz = logu(200, 4000) if metal else logu(30, 120 if kind == "kick" else 400)
        if kind in ("snare", "rimshot") and rng.random() < 0.5:
            v.noise_db = float(rng.uniform(-18, 3))
            v.noise_band = (logu(1000, 4000), logu(5000, 10000))
            v.noise_decay_s = logu(0.04, 0.35)
        if rng.random() < 0.3:
            v.decay_s = max(logu(0.03, 0.6), MIN_DECAY_S.get(kind, 0.0))
            v.decay_hold_s = float(rng.uniform(0.005, 0.03))
        if rng.random() < 0.4:
            v.attack_db = float(rng.uniform(-6, 9))
            v.attack_s = logu(0.002, 0.015)
        v.seed = int(rng.integers(2**31))
        return v

    def apply(self, sample: np.ndarray) -> np.ndarray:
        key = id(sample)
        if key in self._cache:
            return self._cache[key]
        y = sample
        if abs(self.factor - 1.0) > 1e-3:
            y = resample(y, int(round(RENDER_RATE * self.factor)), RENDER_RATE)
        if self.eq_db:
            b, a = _peaking(self.eq_hz, self.eq_db)
            y = lfilter(b, a, y).astype(np.float32)
        if self.tilt_db:
            low = sosfilt(butter(1, self.tilt_hz, btype="low", fs=RENDER_RATE, output="sos"), y)
            high = sosfilt(butter(1, self.tilt_hz, btype="high", fs=RENDER_RATE, output="sos"), y)
            y = (low * 10 ** (-self.tilt_db / 40) + high * 10 ** (self.tilt_db / 40)).astype(np.float32)
        y = self._shape(np.asarray(y, np.float32))
        self._cache[key] = y
        return y

    def _shape(self, y: np.ndarray) -> np.ndarray:
        """The changes of :meth:`random_wide` (none by default)."""
        t = np.arange(len(y)) / RENDER_RATE
        if self.noise_db is not None and len(y):
            lo, hi = self.noise_band
            noise = np.random.default_rng(self.seed).standard_normal(len(y))
            noise = sosfilt(butter(2, (lo, min(hi, 0.45 * RENDER_RATE)), btype="band", fs=RENDER_RATE,
                                   output="sos"), noise)
            env = np.minimum(1.0, t / 0.002) * np.exp(-t / self.noise_decay_s)
            head = y[: int(0.1 * RENDER_RATE)]
            level = float(np.sqrt(np.mean(head**2))) * 10 ** (self.noise_db / 20)
            noise *= env * level / max(float(np.sqrt(np.mean((noise * env)[: len(head)] ** 2))), 1e-12)
            y = y + noise.astype(np.float32)
        if self.lowpass_hz:
            y = sosfilt(butter(2, min(self.lowpass_hz, 0.45 * RENDER_RATE), btype="low", fs=RENDER_RATE,
                               output="sos"), y)
        if self.highpass_hz:
            y = sosfilt(butter(2, self.highpass_hz, btype="high", fs=RENDER_RATE, output="sos"), y)
        if self.decay_s:
            y = y * np.exp(-np.maximum(t - self.decay_hold_s, 0.0) / self.decay_s)
        if self.attack_db:
            y = y * (1.0 + (10 ** (self.attack_db / 20) - 1.0) * np.exp(-t / self.attack_s))
        return np.asarray(y, np.float32)


def _peaking(f0: float, gain_db: float, q: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """RBJ peaking-EQ biquad coefficients."""
    amp = 10 ** (gain_db / 40)
    w0 = 2 * np.pi * min(f0, 0.45 * RENDER_RATE) / RENDER_RATE
    alpha = np.sin(w0) / (2 * q)
    b = np.array([1 + alpha * amp, -2 * np.cos(w0), 1 - alpha * amp])
    a = np.array([1 + alpha / amp, -2 * np.cos(w0), 1 - alpha / amp])
    return b / a[0], a / a[0]


def render(
    notes: list[Note],
    kit: Kit,
    rng: np.random.Generator,
    duration: float | None = None,
    tail: float = 1.0,
    vary: bool = False,
    wide: bool = False,
) -> tuple[np.ndarray, list[Hit]]:
    """Render notes with a kit (dry, mono, RENDER_RATE).

    With ``vary``, each instrument is detuned by up to 4 semitones, given a random
    peaking EQ (+-9 dB), a spectral tilt (+-8 dB), a level offset (-12..+10 dB) and a velocity curve
    (gain = v ** 1.0..2.6 instead of v ** 1.6), to widen the timbres and balances seen in training;
    ``wide`` adds the further changes of :meth:`Variation.random_wide`.

    Notes whose pitch is none of the classes, or whose kind the kit lacks, are left out
    of both the audio and the returned hits. An open hi-hat is choked (20 ms fade) by the
    next hi-hat note.

    Returns
    -------
    audio : np.ndarray [shape=(n,), dtype=float32]
    hits : list of :class:`Hit`, the ground truth
    """
    end = duration if duration is not None else (notes[-1].time + tail if notes else tail)
    n = int(end * RENDER_RATE) + 1
    out = np.zeros(n, np.float32)
    # one instrument per kind for the whole excerpt (like a drummer's kit), detuned and coloured at random
    chosen: dict[str, tuple[object, Variation]] = {}
    hits: list[Hit] = []
    hh_times = [nt.time for nt in notes if KIND_CLASS.get(PITCH_KIND.get(nt.pitch, ""), -1) in (2, 3)]
    for nt in notes:
        if nt.time >= end:
            break
        kind = PITCH_KIND.get(nt.pitch)
        cls = class_of_pitch(nt.pitch)
        if kind is None or cls is None:
            continue
        if kind not in chosen:
            chosen[kind] = (kit.choose(kind, rng), (Variation.random_wide(rng, kind) if wide else
                                                    Variation.random(rng)) if vary else Variation())
        inst, variation = chosen[kind]
        if inst is None:
            continue
        vel = nt.velocity / 127.0
        layer = inst.layer(vel, rng)  # type: ignore[attr-defined]
        gain = layer.gain * inst.gain * variation.gain * vel**variation.curve  # type: ignore[attr-defined]
        sample = variation.apply(layer.audio) * gain * float(10 ** (rng.normal(0, 1.0) / 20))
        if KIND_CLASS[kind] == 3:  # open hi-hat: choke at the next hi-hat note
            later = [t for t in hh_times if t > nt.time + 0.03]
            if later:
                keep = int((later[0] - nt.time) * RENDER_RATE)
                if keep < len(sample):
                    fade = min(int(0.02 * RENDER_RATE), len(sample) - keep)
                    sample = sample[: keep + fade].copy()
                    sample[keep:] *= np.linspace(1, 0, fade, dtype=np.float32)
        start = int(round(nt.time * RENDER_RATE))
        stop = min(n, start + len(sample))
        out[start:stop] += sample[: stop - start]
        hits.append(Hit(nt.time, cls, nt.velocity))
    return out, hits


def room_ir(rng: np.random.Generator) -> np.ndarray:
    """A synthetic room impulse response: direct sound plus exponentially decaying noise."""
    rt60 = rng.uniform(0.15, 0.9)
    length = int(rt60 * RENDER_RATE)
    t = np.arange(length) / RENDER_RATE
    tail = rng.standard_normal(length).astype(np.float32) * np.exp(-6.9 * t / rt60).astype(np.float32)
    sos = butter(2, rng.uniform(2000, 8000), btype="low", fs=RENDER_RATE, output="sos")
    tail = sosfilt(sos, tail).astype(np.float32)
    tail *= 10 ** (rng.uniform(-24, -8) / 20) / max(float(np.sqrt(np.sum(tail**2))), 1e-9)
    ir = tail
    ir[0] = 1.0
    return ir


def augment(audio: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Room reverb, random EQ tilt, noise (SNR 20-60 dB), soft clipping, peak normalisation."""
    x = audio
    if rng.random() < 0.8:
        x = fftconvolve(x, room_ir(rng))[: len(audio)].astype(np.float32)
    if rng.random() < 0.5:
        sos = butter(1, rng.uniform(3000, 10000), btype="low", fs=RENDER_RATE, output="sos")
        x = (x * (1 - (w := rng.uniform(0.2, 0.8))) + w * sosfilt(sos, x)).astype(np.float32)
    if rng.random() < 0.3:
        sos = butter(1, rng.uniform(40, 150), btype="high", fs=RENDER_RATE, output="sos")
        x = sosfilt(sos, x).astype(np.float32)
    rms = float(np.sqrt(np.mean(x**2))) + 1e-9
    noise = rng.standard_normal(len(x)).astype(np.float32)
    if rng.random() < 0.5:  # pinkish noise
        noise = np.cumsum(noise).astype(np.float32)
        noise -= sosfilt(butter(1, 20, btype="low", fs=RENDER_RATE, output="sos"), noise).astype(np.float32)
        noise /= float(np.std(noise)) + 1e-9
    x = x + noise * rms * 10 ** (-rng.uniform(20, 60) / 20)
    if rng.random() < 0.2:
        drive = rng.uniform(1.5, 4.0)
        x = np.tanh(drive * x / (float(np.max(np.abs(x))) + 1e-9)) / np.tanh(drive)
    return normalise(np.asarray(x, np.float32))


def normalise(x: np.ndarray, peak: float = 0.9) -> np.ndarray:
    """Scale to a given peak amplitude."""
    m = float(np.max(np.abs(x)))
    return (x * (peak / m)).astype(np.float32) if m > 0 else x


if __name__ == "__main__":  # run as a program by mistake: say which commands train
    from services.recogniser.training.options import not_a_command

    not_a_command(__spec__.name)
