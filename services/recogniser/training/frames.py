"""Framewise training data: band spectrograms of rendered excerpts and their strikes.

Each excerpt is rendered (:mod:`.excerpts`), turned into the recogniser's band
spectrogram (:func:`~services.recogniser.features.band_spectrogram`, the network's
input) and kept with its true strikes. Targets are made from the strikes when
training (:func:`targets`), so the cache holds only spectra (float16) and strikes.
"""

from __future__ import annotations

import multiprocessing as mp
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from services.recogniser import features as F
from services.recogniser.classes import N_CLASSES
from services.recogniser.training.excerpts import DRY_P, Job, jobs, prepare, render_excerpt

NEIGHBOUR_TARGET = 0.5
"""Target of the frames next to a strike's frame (target widening: the exact frame is uncertain by half a hop)."""


@dataclass
class FrameSet:
    """Spectra of several excerpts, concatenated.

    spec : (n_frames, N_BANDS) float16, excerpt ``e`` is rows ``starts[e]:starts[e + 1]``
    starts : (n_excerpts + 1,) row offsets
    hits : (k, 4) float64: excerpt index, time s (from the excerpt's start), class index, MIDI velocity
    """

    spec: np.ndarray
    starts: np.ndarray
    hits: np.ndarray

    @property
    def n_excerpts(self) -> int:
        return len(self.starts) - 1

    def excerpt(self, e: int) -> np.ndarray:
        return self.spec[self.starts[e] : self.starts[e + 1]]

    def excerpt_hits(self, e: int) -> np.ndarray:
        return self.hits[self.hits[:, 0] == e]

    def save(self, path: Path) -> None:
        np.savez(path, spec=self.spec, starts=self.starts, hits=self.hits)

    @staticmethod
    def load(path: Path) -> FrameSet:
        with np.load(path) as z:
            return FrameSet(z["spec"], z["starts"], z["hits"])


def _one(job: Job) -> tuple[np.ndarray, np.ndarray]:
    audio, hits = render_excerpt(job)
    spec = F.band_spectrogram(audio).astype(np.float16)
    return spec, np.array([[h.time, h.cls, h.velocity] for h in hits], np.float64).reshape(-1, 3)


def make_frames(n: int, seed: int, workers: int, kits: tuple[str, ...], dry_p: float = DRY_P) -> FrameSet:
    """Render ``n`` excerpts with ``kits`` (a share ``dry_p`` dry) into a :class:`FrameSet`."""
    prepare(kits)
    todo = jobs(n, seed, kits, dry_p)
    if workers <= 1:
        parts = [_one(j) for j in todo]
    else:
        with mp.Pool(workers) as pool:
            parts = pool.map(_one, todo, chunksize=4)
    starts = np.concatenate([[0], np.cumsum([len(s) for s, _ in parts])]).astype(np.int64)
    hits = [np.column_stack([np.full(len(h), e, np.float64), h]) for e, (_, h) in enumerate(parts)]
    return FrameSet(np.concatenate([s for s, _ in parts]), starts, np.concatenate(hits))


def targets(n_frames: int, hits: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Frame targets of one excerpt from its hits (rows: time s, class, velocity; or :class:`FrameSet` rows).

    Returns
    -------
    act : (n_frames, N_CLASSES + 1) float32, 1 at each strike's nearest frame, :data:`NEIGHBOUR_TARGET`
        at the frames beside it; the last column is "a strike of any class"
    vel : (n_frames, N_CLASSES) float32, velocity / 127 at strike frames
    vel_mask : (n_frames, N_CLASSES) bool, where ``vel`` is defined
    """
    h = hits[:, -3:]
    act = np.zeros((n_frames, N_CLASSES + 1), np.float32)
    vel = np.zeros((n_frames, N_CLASSES), np.float32)
    mask = np.zeros((n_frames, N_CLASSES), bool)
    frame = np.rint(h[:, 0] * F.FPS).astype(int)
    cls = h[:, 1].astype(int)
    ok = (frame >= 0) & (frame < n_frames)
    frame, cls, v = frame[ok], cls[ok], h[ok, 2]
    for d in (-1, 1):
        f = np.clip(frame + d, 0, n_frames - 1)
        act[f, cls] = np.maximum(act[f, cls], NEIGHBOUR_TARGET)
        act[f, N_CLASSES] = np.maximum(act[f, N_CLASSES], NEIGHBOUR_TARGET)
    act[frame, cls] = 1.0
    act[frame, N_CLASSES] = 1.0
    vel[frame, cls] = np.maximum(vel[frame, cls], v / 127.0)
    mask[frame, cls] = True
    return act, vel, mask
