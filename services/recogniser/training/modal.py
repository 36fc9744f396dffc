"""A training "kit" made with Batteur's own sound synthesis (modal and signal-based models).

The one-shots are rendered by the sound service's public command line
(``python -m services.sound.demo``, run as a subprocess: services never import each
other): a General MIDI file of isolated strikes, each drum note at several velocities,
is played dry and mono, then cut into one sample per strike. The result is a
:class:`~services.recogniser.training.kits.Kit` like a Hydrogen kit, with one
velocity layer per rendered velocity, so :func:`~services.recogniser.training.render.render`
plays Groove performances with it like with any recorded kit.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

import mido
import numpy as np
import soundfile as sf

from services.recogniser.audio import SAMPLE_RATE, resample, to_mono
from services.recogniser.training.kits import Instrument, Kit, Layer

MODAL_KITS = ("batteur-modal", "batteur-synth")
"""Pseudo kit names: Batteur's modal synthesis and its signal-based synthesis."""

KIND_NOTE = {
    "kick": 36, "snare": 38, "stick": 37, "rimshot": 40, "hh_closed": 42, "hh_pedal": 44, "hh_open": 46,
    "tom_high": 48, "tom_mid": 45, "tom_floor": 43, "crash": 49, "china": 52, "splash": 55, "ride": 51,
    "ride_bell": 53,
}
"""Instrument kind -> the General MIDI note the sound demo plays it with."""

VELOCITIES = (20, 45, 70, 95, 120)
"""MIDI velocities rendered, one velocity layer each."""
SPACING_S = 2.5
"""Time between two strikes of the one-shot file, seconds (the longest tail kept)."""
START_S = 0.5
"""The sound demo starts the file this late, seconds."""


def _strike_file(path: Path) -> list[tuple[str, int, float]]:
    """Write the one-shot MIDI file; returns (kind, velocity, time s) per strike."""
    mid = mido.MidiFile(ticks_per_beat=480)
    track = mido.MidiTrack()
    mid.tracks.append(track)
    track.append(mido.MetaMessage("set_tempo", tempo=500_000))  # 120 BPM: 960 ticks per second
    strikes: list[tuple[str, int, float]] = []
    t = 0.0
    for kind in KIND_NOTE:
        for v in VELOCITIES:
            strikes.append((kind, v, t))
            t += SPACING_S
    last = 0
    for kind, v, when in strikes:
        tick = int(round(when * 960))
        track.append(mido.Message("note_on", channel=9, note=KIND_NOTE[kind], velocity=v, time=tick - last))
        track.append(mido.Message("note_off", channel=9, note=KIND_NOTE[kind], velocity=0, time=10))
        last = tick + 10
    mid.save(str(path))
    return strikes


def render_modal_kit(model: str = "modal") -> Kit:
    """Render the one-shots with the sound service's ``model`` ('modal' or 'synth') and make a kit of them.

    Raises
    ------
    RuntimeError
        the sound demo failed (its error output is in the message).
    """
    with tempfile.TemporaryDirectory() as tmp:
        midi = Path(tmp) / "strikes.mid"
        wav = Path(tmp) / "strikes.wav"
        strikes = _strike_file(midi)
        seconds = strikes[-1][2] + 1.0
        cmd = [sys.executable, "-m", "services.sound.demo", "--midi", str(midi), "-o", str(wav), "--mono",
               "--reverb", "0", "--model", model, "--seconds", str(seconds)]
        done = subprocess.run(cmd, capture_output=True, text=True, cwd=Path(__file__).resolve().parents[3])
        if done.returncode != 0 or not wav.exists():
            raise RuntimeError(f"sound demo failed ({' '.join(cmd)}): {done.stderr.strip()[-500:]}")
        data, sr = sf.read(str(wav), dtype="float32", always_2d=False)
    audio = resample(to_mono(np.asarray(data, np.float32)), int(sr), SAMPLE_RATE)
    kit = Kit(name=f"batteur-{model}", licence="Batteur's own synthesis")
    layers: dict[str, list[Layer]] = {}
    edges = [0.0, *[(a + b) / 2 / 127 for a, b in zip(VELOCITIES[:-1], VELOCITIES[1:], strict=True)], 1.0]
    for kind, v, when in strikes:
        a = int(round((START_S + when - 0.005) * SAMPLE_RATE))
        one = audio[a : a + int((SPACING_S - 0.05) * SAMPLE_RATE)]
        peak = float(np.max(np.abs(one))) if one.size else 0.0
        if peak <= 1e-5:
            continue
        above = np.flatnonzero(np.abs(one) > 10 ** (-50 / 20) * peak)
        one = one[int(above[0]) :] / peak  # loudness comes from the velocity curve, timbre from the layer
        i = VELOCITIES.index(v)
        layers.setdefault(kind, []).append(Layer(edges[i], edges[i + 1], 1.0, one.astype(np.float32)))
    for kind, ls in layers.items():
        kit.instruments[kind] = [Instrument(f"{model} {kind}", kind, 1.0, ls)]
    return kit
