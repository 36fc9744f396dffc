"""Offline transcription: audio -> onsets (SuperFlux) -> drum classes and velocities per onset.

Each detected onset is classified by the model's ``offline`` MLP (multi-label: a
kick and a hi-hat struck together are two events at the same time); an onset
whose every class is below threshold is dropped as a false onset, unless the
model's onset output says it is a strike (then it is its most probable class).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from services.recogniser import features as F
from services.recogniser.audio import MAX_DURATION_S, SAMPLE_RATE, load_audio
from services.recogniser.classes import CLASSES
from services.recogniser.model import Classifier, Model, load_model

PEAK = 0.9
"""Audio is scaled to this peak before analysis (as the training audio was)."""


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
"""Two strikes of one class closer than this are one strike (the more probable is kept), seconds."""


def suppress(events: list[DrumEvent], window: float = SUPPRESS_S) -> list[DrumEvent]:
    """Per-class non-maximum suppression: keep the most probable of strikes closer than ``window``."""
    kept: list[DrumEvent] = []
    by_class: dict[int, list[DrumEvent]] = {}
    for e in events:
        by_class.setdefault(e.cls, []).append(e)
    for evs in by_class.values():
        times = np.array([e.time for e in evs])
        taken = np.zeros(len(evs), dtype=bool)
        for i in np.argsort([-e.confidence for e in evs], kind="stable"):
            near = np.abs(times - times[i]) < window
            if not np.any(taken & near):
                taken[i] = True
        kept += [e for e, k in zip(evs, taken, strict=True) if k]
    kept.sort(key=lambda e: (e.time, e.cls))
    return kept


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


def classify(clf: Classifier, feats: np.ndarray, times: np.ndarray, chunk: int = 4096) -> list[DrumEvent]:
    """Turn onset features (n, n_features) at ``times`` (n,) seconds into events (before suppression)."""
    events: list[DrumEvent] = []
    for s in range(0, len(times), chunk):
        x = feats[s : s + chunk]
        prob = clf.probabilities(x)
        vel = clf.velocities(x)
        hit = clf.decide(prob)
        for i, c in zip(*np.nonzero(hit), strict=True):
            events.append(DrumEvent(float(times[s + i]), int(c), int(vel[i, c]), float(prob[i, c])))
    events.sort(key=lambda e: (e.time, e.cls))
    return events


def transcribe(
    audio: np.ndarray, model: Model | None = None, progress: Callable[[float], None] | None = None
) -> list[DrumEvent]:
    """Transcribe mono audio at :data:`SAMPLE_RATE`.

    Parameters
    ----------
    audio : np.ndarray [shape=(n,)]
    model : the classifier (default: the shipped model)
    progress : called with the fraction done, 0..1

    Returns
    -------
    list of :class:`DrumEvent`, sorted by time
    """
    model = model or load_model()
    clf = model.offline
    peak = float(np.max(np.abs(audio))) if len(audio) else 0.0
    x = audio * (PEAK / peak) if peak > 0 else audio
    spec = F.band_spectrogram(x, progress=(lambda f: progress(0.9 * f)) if progress else None)
    odf = F.superflux(spec)
    frames = F.pick_onsets(odf, clf.delta)
    times = np.maximum(F.frame_times(len(odf))[frames] + clf.time_offset_s, 0.0)
    events = group_chords(suppress(classify(clf, F.onset_features(spec, odf, frames, clf.offsets), times)))
    if progress:
        progress(1.0)
    return events


def transcribe_file(
    path: str | Path,
    model: Model | None = None,
    progress: Callable[[float], None] | None = None,
    max_duration_s: float = MAX_DURATION_S,
) -> tuple[list[DrumEvent], float]:
    """Read and transcribe an audio file; returns the events and the duration in seconds.

    Raises :class:`~services.recogniser.errors.AudioFileError` for unusable files.
    """
    audio = load_audio(path, max_duration_s=max_duration_s)
    return transcribe(audio, model, progress), len(audio) / SAMPLE_RATE
