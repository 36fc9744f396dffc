"""Per-strike voices (samples, synthesis, noise components) and the voice pool.

A voice renders mono audio block by block, starting ``delay`` samples into
its first block (sample-accurate onsets). The pool renders every active voice
into its instrument's bus and enforces a voice limit: when a new voice would
exceed it, the quietest voice (ties: the oldest) is stolen with a short
fade-out instead of being cut, so stealing never clicks.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
from scipy import signal

F32 = npt.NDArray[np.float32]
F64 = npt.NDArray[np.float64]

STEAL_FADE_S = 0.005
"""Fade-out of a stolen voice, seconds."""


def bandpass(lo_hz: float, hi_hz: float, sample_rate: float) -> F64:
    """Second-order Butterworth band-pass as second-order sections: designed once per band, not per strike
    (SciPy takes about 0.3 ms a design, in the render loop; a strike's click and snare wires each need one, and
    their bands repeat). A copy: ``sosfilt`` wants a writable array."""
    return _bandpass_design(lo_hz, hi_hz, sample_rate).copy()


@functools.lru_cache(maxsize=256)
def _bandpass_design(lo_hz: float, hi_hz: float, sample_rate: float) -> F64:
    return np.asarray(signal.butter(2, [lo_hz, hi_hz], btype="bandpass", fs=sample_rate, output="sos"))


class Voice:
    """Base class: subclasses implement :meth:`generate`.

    Parameters
    ----------
    instrument : str
        Id of the instrument bus the voice plays into.
    delay : int
        Samples of silence before the voice starts (its onset inside the first block).
    """

    def __init__(self, instrument: str, delay: int = 0) -> None:
        self.instrument = instrument
        self.delay = int(delay)
        self.done = False
        self.age = 0  # samples rendered
        self.level = 1.0  # rough current amplitude, for stealing
        self._fade_left = -1
        self._fade_len = 1
        self._buf: F64 = np.zeros(0)
        self._finished = False
        self.press_exempt = False  # True: follows presses itself (the snare wires follow the head's damping)
        self._press_gain = 1.0  # what presses have taken off so far (they do not give it back when lifted)

    CHUNK = 2048
    """Samples synthesised per call of :meth:`synth` (amortises per-call overhead over several blocks)."""

    def synth(self, n: int) -> F64:
        """Synthesise the next ``n`` samples (float64); set ``self._finished`` when nothing follows."""
        raise NotImplementedError

    def generate(self, n: int) -> F64:
        """The next ``n`` samples of the voice (float64); sets ``self.done`` after the last one."""
        parts = []
        need = n
        while need > 0:
            if self._buf.shape[0] == 0:
                if self._finished:
                    parts.append(np.zeros(need))
                    break
                self._buf = self.synth(self.CHUNK)
            take = self._buf[:need]
            self._buf = self._buf[need:]
            parts.append(take)
            need -= take.shape[0]
        if self._finished and self._buf.shape[0] == 0:
            self.done = True
        return parts[0] if len(parts) == 1 else np.concatenate(parts)

    def release(self, n_samples: int) -> None:
        """Fade out linearly over ``n_samples`` and finish."""
        if self._fade_left < 0:
            self._fade_left = max(int(n_samples), 1)
            self._fade_len = self._fade_left

    def render(self, out: F32, press_per_sample: float = 0.0) -> None:
        """Add the voice's next block into ``out`` (shape (n,)), decaying by ``press_per_sample`` more nepers a
        sample (a press on its instrument)."""
        n = out.shape[0]
        start = min(self.delay, n)
        self.delay -= start
        if start >= n or self.done:
            return
        x = self.generate(n - start)
        if press_per_sample > 0.0 or self._press_gain != 1.0:
            env = self._press_gain * np.exp(-press_per_sample * np.arange(1, x.shape[0] + 1))
            x = x * env
            self._press_gain = float(env[-1])
        if self._fade_left >= 0:
            k = x.shape[0]
            ramp = (self._fade_left - np.arange(k)) / self._fade_len
            x = x * np.clip(ramp, 0.0, 1.0)
            self._fade_left -= k
            if self._fade_left <= 0:
                self.done = True
        out[start:] += x.astype(np.float32)
        self.age += x.shape[0]


@dataclass
class VoicePool:
    """Active voices with a limit and graceful stealing.

    Attributes
    ----------
    max_voices : int
        Voices allowed at once (voices being faded out after stealing do not count).
    sample_rate : float
        Hz.
    stolen : int
        Voices stolen so far.
    """

    max_voices: int = 64
    sample_rate: float = 48000.0
    voices: list[Voice] = field(default_factory=list)
    stolen: int = 0
    press_rates: dict[str, float] = field(default_factory=dict)
    """Instrument id -> decay rate its presses add to its voices, 1/s (only instruments pressed now)."""

    def _playing(self) -> list[Voice]:
        return [v for v in self.voices if v._fade_left < 0 and not v.done]

    def add(self, voice: Voice) -> None:
        """Start a voice, stealing the quietest (then oldest) one when over the limit."""
        playing = self._playing()
        while len(playing) >= self.max_voices and playing:
            victim = min(playing, key=lambda v: (v.level, -v.age))
            victim.release(int(STEAL_FADE_S * self.sample_rate))
            playing.remove(victim)
            self.stolen += 1
        self.voices.append(voice)

    def render(self, bus: Callable[[str], F32]) -> dict[str, Exception]:
        """Render every voice into ``bus(instrument_id)`` and drop finished ones. A voice that raises is dropped
        and the others play: returns the instruments whose voices raised, with the first exception of each (the
        caller silences them)."""
        failed: dict[str, Exception] = {}
        per_sample = {inst: rate / self.sample_rate for inst, rate in self.press_rates.items()}
        for v in self.voices:
            try:
                if per_sample:
                    v.render(bus(v.instrument), 0.0 if v.press_exempt else per_sample.get(v.instrument, 0.0))
                else:
                    v.render(bus(v.instrument))
            except Exception as exc:  # noqa: BLE001 - a bug in one voice must not take every drum's block
                v.done = True
                failed.setdefault(v.instrument, exc)
        self.voices = [v for v in self.voices if not v.done]
        return failed

    @property
    def active(self) -> int:
        return len(self.voices)


class SampleVoice(Voice):
    """Plays a recorded sample at a playback rate, with gain and a one-pole low-pass (soft strikes are darker)."""

    def __init__(
        self, instrument: str, data: F64, gain: float, rate: float = 1.0, cutoff_hz: float = 20000.0,
        sample_rate: float = 48000.0, delay: int = 0,
    ) -> None:
        super().__init__(instrument, delay)
        self.data = data
        self.gain = float(gain)
        self.rate = float(rate)
        self.pos = 0.0
        a = float(np.exp(-2.0 * np.pi * min(cutoff_hz, 0.45 * sample_rate) / sample_rate))
        self._b, self._a = [1.0 - a], [1.0, -a]
        self._zi = np.zeros(1)
        self.level = abs(self.gain)

    def synth(self, n: int) -> F64:
        idx = self.pos + self.rate * np.arange(n)
        self.pos += self.rate * n
        x = np.interp(idx, np.arange(self.data.shape[0]), self.data, right=0.0) * self.gain
        y, self._zi = signal.lfilter(self._b, self._a, x, zi=self._zi)
        if self.pos >= self.data.shape[0]:
            self._finished = True
        remaining = 1.0 - self.pos / self.data.shape[0]
        self.level = abs(self.gain) * max(remaining, 0.0)
        return np.asarray(y)


class NoiseVoice(Voice):
    """Band-passed noise with an attack/decay envelope (snare wires, hi-hat chick, stick tick).

    Parameters
    ----------
    band : tuple[float, float]
        Pass band, Hz.
    amplitude : float
        Peak amplitude.
    attack, decay : float
        Attack time and exponential decay time constant, seconds.
    seed : int
        Noise seed (deterministic renders).
    """

    def __init__(
        self, instrument: str, band: tuple[float, float], amplitude: float, attack: float, decay: float,
        seed: int, sample_rate: float = 48000.0, delay: int = 0,
    ) -> None:
        super().__init__(instrument, delay)
        lo, hi = band
        hi = min(hi, 0.45 * sample_rate)
        self.sos = bandpass(float(lo), float(hi), float(sample_rate))
        self.zi = np.zeros((self.sos.shape[0], 2))
        self.rng = np.random.default_rng(seed)
        self.amplitude = float(amplitude)
        self.attack = max(float(attack), 1e-4)
        self.decay = max(float(decay), 1e-3)
        self.sr = float(sample_rate)
        self.t = 0
        self.level = self.amplitude
        self._knee: tuple[float, float] | None = None
        """(seconds into the voice, nepers decayed by then) where the decay last changed; None: never changed."""

    def _nepers(self, t: F64) -> F64:
        """Decay of the envelope at ``t`` seconds into the voice, nepers (the attack aside)."""
        if self._knee is None:
            return t / self.decay
        t0, n0 = self._knee
        return n0 + (t - t0) / self.decay

    def set_decay(self, decay: float) -> None:
        """Decay with time constant ``decay`` (seconds) from the next sample handed out (a head damped while its
        wires ring); samples synthesised ahead are rescaled, so the change lands on that sample."""
        decay = max(float(decay), 1e-3)
        if decay == self.decay:
            return
        ahead = self._buf.shape[0]
        t0 = (self.t - ahead) / self.sr
        n0 = float(self._nepers(np.array(t0)))
        if ahead:
            self._buf = self._buf * np.exp(-(np.arange(ahead) / self.sr) * (1.0 / decay - 1.0 / self.decay))
        self._knee, self.decay = (t0, n0), decay
        self.level = self.amplitude * float(np.exp(-n0))

    def synth(self, n: int) -> F64:
        t = (self.t + np.arange(n)) / self.sr
        self.t += n
        if self._knee is None:  # the original expression: renders without a change stay bit-identical
            env = self.amplitude * (1.0 - np.exp(-t / self.attack)) * np.exp(-t / self.decay)
            finished = t[-1] > self.attack + 9.0 * self.decay  # below -78 dB
        else:
            nepers = self._nepers(t)
            env = self.amplitude * (1.0 - np.exp(-t / self.attack)) * np.exp(-nepers)
            finished = t[-1] > self.attack and nepers[-1] > 9.0
        noise = self.rng.standard_normal(n)
        y, self.zi = signal.sosfilt(self.sos, noise, zi=self.zi)
        self.level = float(env[-1])
        if finished:
            self._finished = True
        return np.asarray(y * env * 2.0)
