"""A drum pattern rendered with the samples of a kit the recogniser never trained on (tests/data/recogniser)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import soundfile as sf

DATA = Path(__file__).resolve().parents[1] / "data" / "recogniser"
RATE = 44100
"""Sample rate of the held-out kit's test samples and of the pattern, Hz."""


@dataclass(frozen=True)
class Pattern:
    """A rendered pattern: audio (mono, ``sample_rate`` Hz) and its notes (time s, class name, velocity)."""

    audio: np.ndarray
    notes: list[tuple[float, str, int]]
    sample_rate: int = RATE

    def times(self, name: str) -> np.ndarray:
        return np.array([t for t, n, _ in self.notes if n == name])


def load_sample(name: str) -> np.ndarray:
    data, sr = sf.read(DATA / f"blackpearl_{name}.flac", dtype="float32")
    assert sr == RATE
    return data


def render_pattern(bars: int = 4, bpm: float = 100.0, seed: int = 3) -> Pattern:
    """Rock beat: closed hi-hat eighths, kick on 1, 3 and the and of 3, snare on 2 and 4;
    the last bar ends with a tom fill, the first beat also has a crash, the second-to-last
    bar has an open hi-hat on its last eighth."""
    rng = np.random.default_rng(seed)
    beat = 60.0 / bpm
    notes: list[tuple[float, str, int]] = []
    for b in range(bars):
        t0 = 0.2 + b * 4 * beat
        last = b == bars - 1
        for e in range(8):
            t = t0 + e * beat / 2
            if last and e >= 4:
                notes.append((t, "tom_high" if e < 6 else "tom_floor", 110))
                continue
            if b == bars - 2 and e == 7:
                notes.append((t, "hihat_open", 100))
            else:
                notes.append((t, "hihat_closed", int(rng.integers(70, 100))))
        notes += [(t0, "kick", 110), (t0 + 2 * beat, "kick", 105), (t0 + 2.5 * beat, "kick", 95)]
        notes += [(t0 + beat, "snare", 115), (t0 + 3 * beat, "snare", 112)]
    notes.append((0.2, "crash", 120))
    notes.sort()
    length = int((0.2 + bars * 4 * beat + 1.5) * RATE)
    audio = np.zeros(length, np.float32)
    samples = {n: load_sample(n) for n in {n for _, n, _ in notes}}
    for t, n, v in notes:
        s = samples[n] * (v / 127.0) ** 1.6
        i = int(round(t * RATE))
        audio[i : i + len(s)] += s[: length - i]
    audio += 1e-4 * rng.standard_normal(length).astype(np.float32)
    return Pattern(audio * (0.9 / float(np.max(np.abs(audio)))), notes)


