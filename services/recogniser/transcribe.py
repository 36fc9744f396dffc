"""Offline transcription: audio -> band spectrogram -> framewise network -> strikes per class.

The model's ``offline`` network (:mod:`services.recogniser.framenet`) gives, for every
10 ms frame, the probability that each class is struck there; each class's peaks
above its threshold are its strikes (a kick and a hi-hat struck together are two
events at the same time), with the velocity the network gives at that frame.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from services.recogniser.audio import MAX_DURATION_S, SAMPLE_RATE, load_audio, quantum, resample
from services.recogniser.classes import CLASSES
from services.recogniser.features import full_rate_hz
from services.recogniser.framenet import FrameNet
from services.recogniser.model import Model, load_model

PEAK = 0.9
"""Audio is scaled to this peak before analysis (as the training audio was)."""
NOISE_FILL = 0.3
"""Steady noise added to a file stored as integers before it is scaled to :data:`PEAK`, its RMS in steps of the
file's quantisation (:func:`~services.recogniser.audio.quantum`). A quiet take saved in 16 bits without dither
has its soft sounds cut into steps and its decays gated to digital silence; scaled up to the peak, the network
heard strikes there. The noise makes that quantisation more like what dither would have made it, a steady floor
like the noise of the training renders (SNR 20-60 dB). Chosen on the validation kit at -40 dBFS among 0.3, 0.6
and 1.0 (onsets F 0.888 -> 0.893, snare 0.808 -> 0.839; more noise lowered the onsets and hi-hats). Only for a
quiet file: :data:`FILL_BELOW_STEPS` (docs/recogniser.md, "Your recordings")."""
FILL_BELOW_STEPS = 1024
""":data:`NOISE_FILL` is added only to a file whose peak is under this many quantisation steps (10 bits; 16 bits:
-30 dBFS): at -20 dBFS it cost the validation kit's onsets 0.002 (0.903 -> 0.901), at full level a snare, while a
16-bit take is heard as in float down to -20 dBFS."""
NOISE_BLOCK = 1 << 20
"""Samples of :data:`NOISE_FILL` drawn at a time (bounds the memory of an hour's file)."""


@dataclass(frozen=True)
class DrumEvent:
    """One recognised strike.

    time : onset, seconds from the start of the audio
    cls : class index into :data:`~services.recogniser.classes.CLASSES`
    velocity : MIDI velocity 1..127
    confidence : the classifier's probability 0..1
    """

    time: float
    cls: int
    velocity: int
    confidence: float

    @property
    def note(self) -> int:
        """General MIDI drum note."""
        return CLASSES[self.cls].note

    @property
    def name(self) -> str:
        return CLASSES[self.cls].name


SUPPRESS_S = 0.035
"""Live mode: a strike of a class this soon after the previous one of that class is not sent again, seconds."""


CHORD_S = 0.02
"""Strikes of different classes closer than this to the first of a group are one chord: they get its time,
seconds. One strike often makes two candidate onsets 20 ms apart (a kick's thump, then the hi-hat's
attack) that the classifier may label with different classes; grouping keeps them one onset."""


def group_chords(events: list[DrumEvent], window: float = CHORD_S) -> list[DrumEvent]:
    """Give every event within ``window`` of the first event of its group that group's time.

    Events arrive sorted by time; a group starts at an event farther than ``window`` from the
    current group's first event, or of a class the group already has (a second strike)."""
    out: list[DrumEvent] = []
    start = -np.inf
    classes: set[int] = set()
    for e in events:
        if e.time - start < window and e.cls not in classes:
            out.append(DrumEvent(start, e.cls, e.velocity, e.confidence))
        else:
            start = e.time
            classes = set()
            out.append(e)
        classes.add(e.cls)
    out.sort(key=lambda e: (e.time, e.cls))
    return out


def strikes(net: FrameNet, out: np.ndarray) -> list[DrumEvent]:
    """Events from the network's framewise outputs (:meth:`FrameNet.forward`), grouped into chords."""
    found = net.detect(out)
    times = net.positions(out, found) / net.fps + net.time_offset_s
    events = [DrumEvent(max(0.0, float(s)), c, v, p) for s, (_, c, v, p) in zip(times, found, strict=True)]
    events.sort(key=lambda e: (e.time, e.cls))
    return group_chords(events, net.chord_s) if net.chord_s > 0 else events


def transcribe(
    audio: np.ndarray, model: Model | None = None, progress: Callable[[float], None] | None = None,
    sample_rate: int = SAMPLE_RATE, step: float | None = None,
) -> list[DrumEvent]:
    """Transcribe mono audio.

    Parameters
    ----------
    audio : np.ndarray [shape=(n,)], at ``sample_rate`` Hz (resampled to the network's rate if it differs)
    model : the classifier (default: the shipped model)
    progress : called with the fraction done, 0..1
    sample_rate : Hz (default :data:`SAMPLE_RATE`)
    step : the quantisation step of the file the audio was read from, full scale 1 (None: float audio;
        :func:`~services.recogniser.audio.quantum`): see :data:`NOISE_FILL`

    Returns
    -------
    list of :class:`DrumEvent`, sorted by time
    """
    net = (model or load_model()).offline
    events = strikes(net, network_outputs(audio, net, progress, sample_rate, step))
    if progress:
        progress(1.0)
    return events


def network_outputs(
    audio: np.ndarray, net: FrameNet, progress: Callable[[float], None] | None = None,
    sample_rate: int = SAMPLE_RATE, step: float | None = None,
) -> np.ndarray:
    """The offline network's framewise outputs for mono audio: (frames, N_OUT), frames ``net.hop`` samples apart
    at ``net.sample_rate`` (:meth:`FrameNet.forward`), the audio resampled to that rate and scaled to
    :data:`PEAK` first, its spectrograms adapted to the file (:meth:`FrameNet.adapt`). :func:`strikes` turns
    them into events; ``progress`` is called up to 0.95. Beyond its ends the audio stays at its level there: a
    file resting away from zero at its edges (a silent lead-in or tail moved off zero by the removal of the mean,
    as in Batteur's renders) would otherwise step there, heard as a strike at 0 s or at the end. Audio read from
    integers (``step``: their quantisation step, full scale 1) and quiet (:data:`FILL_BELOW_STEPS`) gets
    :data:`NOISE_FILL` first."""
    if sample_rate != net.sample_rate:
        audio = resample(audio, sample_rate, net.sample_rate)
    peak = float(np.max(np.abs(audio))) if len(audio) else 0.0
    x = audio * (PEAK / peak) if peak > 0 else audio
    if rms := fill_rms(peak, step):
        fill_noise(x, rms * PEAK / peak)
    spec = net.adapt(net.spectrogram(x, progress=(lambda f: progress(0.5 * f)) if progress else None,
                                     hold_edges=True))
    return net.forward(spec, progress=(lambda f: progress(0.5 + 0.45 * f)) if progress else None)


def fill_rms(peak: float, step: float | None) -> float:
    """The RMS of :data:`NOISE_FILL` for audio of ``peak`` (full scale 1, before it is scaled) read from integers
    of quantisation ``step`` (None: floats), in the audio's units; 0.0 for none (floats, or a peak of
    :data:`FILL_BELOW_STEPS` steps or more). The one rule of the file path and of the live one
    (:func:`~services.recogniser.node.play_file`)."""
    return NOISE_FILL * step if step and 0 < peak < FILL_BELOW_STEPS * step else 0.0


def fill_noise(x: np.ndarray, rms: float) -> None:
    """Add white Gaussian noise of ``rms`` to ``x`` (float32) in place, the same on every run (seeded), drawn
    :data:`NOISE_BLOCK` samples at a time."""
    rng = np.random.default_rng(0)
    for a in range(0, len(x), NOISE_BLOCK):
        part = x[a : a + NOISE_BLOCK]
        part += np.float32(rms) * rng.standard_normal(len(part), dtype=np.float32)


def transcribe_file(
    path: str | Path,
    model: Model | None = None,
    progress: Callable[[float], None] | None = None,
    max_duration_s: float = MAX_DURATION_S,
    warn: Callable[[str], None] | None = None,
) -> tuple[list[DrumEvent], float]:
    """Read and transcribe an audio file; returns the events and the duration in seconds.

    Raises :class:`~services.recogniser.errors.AudioFileError` for unusable files; ``warn`` hears of suspect
    ones (:func:`~services.recogniser.audio.load_audio`), and of a file sampled too slowly to fill the network's
    top bands (a 22,050 Hz file for the shipped network: :func:`~services.recogniser.features.full_rate_hz`) or
    holding nothing there. A quiet file stored as integers gets :data:`NOISE_FILL` at its quantisation step.
    """
    model = model or load_model()
    rate = model.offline.sample_rate
    audio = load_audio(path, max_duration_s=max_duration_s, sample_rate=rate, warn=warn,
                       full_rate_hz=full_rate_hz(model.offline.bands))
    return transcribe(audio, model, progress, rate, quantum(path)), len(audio) / rate
