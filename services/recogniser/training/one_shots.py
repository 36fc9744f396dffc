"""Training kits made of rendered one-shots: a General MIDI file of isolated strikes, cut into velocity layers.

Batteur's own synthesis (:mod:`.modal`) and General MIDI soundfonts (:mod:`.soundfont`) both render
this file (each drum note at :data:`VELOCITIES`, :data:`SPACING_S` apart, the first at
``start_s`` in the audio) and cut the audio into a
:class:`~services.recogniser.training.kits.Kit` like a Hydrogen kit, so
:func:`~services.recogniser.training.render.render` plays Groove performances with it
like with any recorded kit.
"""

from __future__ import annotations

from pathlib import Path

import mido
import numpy as np

from services.recogniser.audio import resample, to_mono
from services.recogniser.training.kits import RENDER_RATE, Instrument, Kit, Layer

KIND_NOTE = {
    "kick": 36, "snare": 38, "stick": 37, "rimshot": 40, "hh_closed": 42, "hh_pedal": 44, "hh_open": 46,
    "tom_high": 48, "tom_mid": 45, "tom_floor": 43, "crash": 49, "china": 52, "splash": 55, "ride": 51,
    "ride_bell": 53,
}
"""Instrument kind -> the General MIDI note it is rendered with."""

VELOCITIES = (20, 45, 70, 95, 120)
"""MIDI velocities rendered, one velocity layer each."""
SPACING_S = 2.5
"""Time between two strikes of the one-shot file, seconds (the longest tail kept)."""

Strike = tuple[str, int, float]
"""(instrument kind, MIDI velocity, time from the first strike, seconds)."""


def write_strike_file(path: Path, program: int | None = None, start_s: float = 0.0, channel: int = 9,
                      notes: dict[str, int] | None = None) -> list[Strike]:
    """Write the one-shot MIDI file (on ``channel``, 0-based, default 9: General MIDI's drums; ``program``: a
    drum kit's program change first, as General MIDI soundfonts select their kits; the first strike ``start_s``
    seconds in; ``notes``: kind -> note of the kinds to strike, default :data:`KIND_NOTE`); returns its strikes
    (times from the first strike)."""
    notes = KIND_NOTE if notes is None else notes
    mid = mido.MidiFile(ticks_per_beat=480)
    track = mido.MidiTrack()
    mid.tracks.append(track)
    track.append(mido.MetaMessage("set_tempo", tempo=500_000))  # 120 BPM: 960 ticks per second
    if program is not None:
        track.append(mido.Message("program_change", channel=channel, program=program, time=0))
    strikes: list[Strike] = []
    t = 0.0
    for kind in notes:
        for v in VELOCITIES:
            strikes.append((kind, v, t))
            t += SPACING_S
    last = 0
    for kind, v, when in strikes:
        tick = int(round((start_s + when) * 960))
        track.append(mido.Message("note_on", channel=channel, note=notes[kind], velocity=v, time=tick - last))
        track.append(mido.Message("note_off", channel=channel, note=notes[kind], velocity=0, time=10))
        last = tick + 10
    mid.save(str(path))
    return strikes


def trimmed(one: np.ndarray) -> np.ndarray | None:
    """A one-shot (samples,) from its first sample within 50 dB of its peak, scaled to a peak of 1 (float32);
    None if it is silent."""
    peak = float(np.max(np.abs(one))) if one.size else 0.0
    if peak <= 1e-5:
        return None
    above = np.flatnonzero(np.abs(one) > 10 ** (-50 / 20) * peak)
    return (one[int(above[0]) :] / peak).astype(np.float32)


def cut_kit(name: str, licence: str, audio: np.ndarray, sample_rate: int, strikes: list[Strike],
            start_s: float) -> Kit:
    """The kit of one rendered strike file: ``audio`` (samples, or (samples, channels)) at ``sample_rate``
    Hz, its first strike at ``start_s`` seconds. Each one-shot starts at its first sample within 50 dB of its
    peak and is scaled to a peak of 1 (loudness comes from the velocity curve, timbre from the layer); a
    silent one (the kit lacks the note) is left out."""
    mono = resample(to_mono(np.asarray(audio, np.float32)), int(sample_rate), RENDER_RATE)
    kit = Kit(name=name, licence=licence)
    layers: dict[str, list[Layer]] = {}
    edges = [0.0, *[(a + b) / 2 / 127 for a, b in zip(VELOCITIES[:-1], VELOCITIES[1:], strict=True)], 1.0]
    for kind, v, when in strikes:
        a = max(0, int(round((start_s + when - 0.005) * RENDER_RATE)))
        one = trimmed(mono[a : a + int((SPACING_S - 0.05) * RENDER_RATE)])
        if one is None:
            continue
        i = VELOCITIES.index(v)
        layers.setdefault(kind, []).append(Layer(edges[i], edges[i + 1], 1.0, one))
    for kind, ls in layers.items():
        kit.instruments[kind] = [Instrument(f"{name} {kind}", kind, 1.0, ls)]
    return kit


if __name__ == "__main__":  # run as a program by mistake: say which commands train
    from services.recogniser.training.options import not_a_command

    not_a_command(__spec__.name)
