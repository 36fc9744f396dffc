"""Training examples of the live classifier: candidate onsets of rendered audio, their context features and labels."""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from services.recogniser import features as F
from services.recogniser.classes import N_CLASSES
from services.recogniser.training.render import Hit

GROOVE_DIR = Path("/work/shared/data/groove")
BACK_OFFSETS = (-8, -5, -3)
"""Earlier context frames (80, 50, 30 ms before): what was already ringing, so a candidate in a loud
strike's tail can be told from a new soft strike."""
LIVE_OFFSETS = (*BACK_OFFSETS, -2, -1, 0, 1)
"""Context frames for live mode (needs audio up to about 33 ms after the onset)."""
CANDIDATE_DELTA = 0.06
"""Low onset threshold: the classifier rejects the false candidates."""
MATCH_S = 0.04
"""A true hit labels the nearest candidate onset within this distance, seconds ..."""
WIDEN_S = 0.021
"""... and every other candidate this close (one candidate spacing), seconds."""


def groove_files(split: str) -> list[tuple[Path, float]]:
    """(MIDI path, duration s) of the Groove files of a split ('train' or 'validation')."""
    out = []
    with open(GROOVE_DIR / "info.csv") as f:
        for row in csv.DictReader(f):
            if row["split"] == split:
                out.append((GROOVE_DIR / row["midi_filename"], float(row["duration"])))
    return out


class GrooveMissingError(RuntimeError):
    """The Groove MIDI Dataset the trainers render is not where they read it."""


def require_groove(splits: tuple[str, ...] = ("train",), root: Path | None = None) -> None:
    """Raise :class:`GrooveMissingError` unless ``root`` (default :data:`GROOVE_DIR`) holds the dataset's
    ``info.csv`` and every MIDI file of ``splits`` (checked before rendering starts, not by a worker midway)."""
    root = GROOVE_DIR if root is None else root
    hint = (f"unpack the Groove MIDI Dataset (groove-v1.0.0-midionly.zip, "
            f"https://magenta.tensorflow.org/datasets/groove) so that {root / 'info.csv'} exists")
    try:
        with open(root / "info.csv", newline="") as f:
            listed = list(csv.DictReader(f))
        rows = [r for r in listed if r.get("split") in splits]
        missing = [r["midi_filename"] for r in rows if not (root / r["midi_filename"]).is_file()]
    except (OSError, KeyError, csv.Error, UnicodeDecodeError) as exc:
        raise GrooveMissingError(f"cannot read the Groove MIDI Dataset in {root} ({exc}): {hint}") from exc
    if not rows:
        held = sorted({str(r.get("split")) for r in listed if r.get("split")})
        if held:  # the dataset is there: a split it does not have (a copy of some splits only)
            raise GrooveMissingError(f"{root / 'info.csv'} lists no performance of the {'/'.join(splits)} split "
                                     f"(it lists the {', '.join(held)} split{'s' if len(held) > 1 else ''})")
        raise GrooveMissingError(f"{root / 'info.csv'} lists no performance of the {'/'.join(splits)} split: {hint}")
    if missing:
        raise GrooveMissingError(f"{len(missing)} of the {len(rows)} Groove MIDI files of the {'/'.join(splits)} "
                                 f"split are missing in {root}, e.g. {missing[0]}: {hint}")


@dataclass
class Examples:
    """Candidate onsets of one or more excerpts."""

    x_live: np.ndarray  # (n, len(LIVE_OFFSETS) * N_BANDS)
    y: np.ndarray  # (n, N_CLASSES) 0/1
    velocity: np.ndarray  # (n, N_CLASSES) 0..127 (0: class absent)
    dt: np.ndarray  # (n,) true time - frame time of the earliest matched hit, s (nan: none)
    missed: int  # true hits that no candidate matched
    time: np.ndarray  # (n,) candidate frame time, s
    excerpt: np.ndarray  # (n,) index of the excerpt the candidate comes from
    hits: np.ndarray  # (k, 3) every true hit: excerpt index, time s, class index


def label(audio: np.ndarray, hits: list[Hit], delta: float = CANDIDATE_DELTA) -> Examples:
    """Detect candidate onsets in ``audio`` (mono at :data:`~services.recogniser.audio.SAMPLE_RATE`, the live
    classifier's rate) and label them with ``hits``."""
    spec = F.band_spectrogram(audio)
    odf = F.superflux(spec)
    frames = F.pick_onsets(odf, delta)
    times = F.frame_times(len(odf))[frames]
    y = np.zeros((len(frames), N_CLASSES), np.float32)
    vel = np.zeros((len(frames), N_CLASSES), np.float32)
    dt = np.full(len(frames), np.nan)
    missed = 0
    for h in hits:
        if len(times) == 0:
            missed += 1
            continue
        dist = np.abs(times - h.time)
        i = int(np.argmin(dist))
        if dist[i] > MATCH_S:
            missed += 1
            continue
        # the nearest candidate and any other within WIDEN_S are positive (inference keeps the most probable)
        for j in {i, *np.flatnonzero(dist <= WIDEN_S).tolist()}:
            y[j, h.cls] = 1
            vel[j, h.cls] = max(vel[j, h.cls], h.velocity)
        d = h.time - times[i]
        if np.isnan(dt[i]) or abs(d) < abs(dt[i]):
            dt[i] = d
    x_live = F.onset_features(spec, odf, frames, LIVE_OFFSETS)
    truth = np.array([[0.0, h.time, h.cls] for h in hits], dtype=np.float64).reshape(-1, 3)
    return Examples(x_live, y, vel, dt, missed, times.astype(np.float64), np.zeros(len(frames), int), truth)


FIELDS = ("x_live", "y", "velocity", "dt", "missed", "time", "excerpt", "hits")


def concat(parts: list[Examples]) -> Examples:
    """One set of examples from several excerpts (renumbering the excerpts)."""
    hits = [np.column_stack([np.full(len(p.hits), i, float), p.hits[:, 1:]]) for i, p in enumerate(parts)]
    return Examples(
        np.concatenate([p.x_live for p in parts]),
        np.concatenate([p.y for p in parts]), np.concatenate([p.velocity for p in parts]),
        np.concatenate([p.dt for p in parts]), sum(p.missed for p in parts),
        np.concatenate([p.time for p in parts]), np.concatenate([np.full(len(p.y), i) for i, p in enumerate(parts)]),
        np.concatenate(hits) if hits else np.zeros((0, 3)),
    )


if __name__ == "__main__":  # run as a program by mistake: say which commands train
    from services.recogniser.training.options import not_a_command

    not_a_command(__spec__.name)
