"""Training excerpts: 30 s of a Groove train-split performance rendered with a (possibly mixed) kit.

Shared by both trainers (the per-candidate MLP of :mod:`.train` and the framewise
network of :mod:`.train_net`). Deterministic for a job's seed.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

from services.recogniser.model import MODEL_PATH
from services.recogniser.training.dataset import groove_files
from services.recogniser.training.kits import (
    KIND_CLASS,
    TRAIN_KITS,
    VALID_KITS,
    Kit,
    KitsMissingError,
    load_kit,
    require_kits,
)
from services.recogniser.training.modal import MODAL_KITS, render_modal_kit
from services.recogniser.training.render import Hit, Note, augment, normalise, read_notes, render

FIT_KITS = TRAIN_KITS + MODAL_KITS
"""Kits the models are fitted on: the Hydrogen training kits and Batteur's own synthesis."""
EXCERPT_S = 30.0
"""Length of one excerpt, seconds."""
VARY_P = 0.9
"""Fraction of excerpts whose instruments get a random detune, EQ, level and velocity curve."""
MIX_P = 0.5
"""Fraction of excerpts played on a kit mixed from several (each instrument kind from a random kit)."""
DRY_P = 0.3
"""Fraction of excerpts left dry (no room, EQ, noise or clipping)."""
VALID_DRY_P = 0.5
"""Fraction of the validation kit's excerpts left dry."""

Job = tuple[int, str, float, tuple[str, ...], float]
"""(seed, MIDI path, performance duration s, kit names, share left dry)."""

_KITS: dict[str, Kit] = {}


def load_any_kit(name: str) -> Kit:
    """A Hydrogen kit, or one of Batteur's own synthesised kits (:data:`MODAL_KITS`), loaded once per process."""
    if name not in _KITS:
        _KITS[name] = render_modal_kit(name.removeprefix("batteur-")) if name in MODAL_KITS else load_kit(name)
    return _KITS[name]


def prepare(kits: tuple[str, ...]) -> None:
    """Make the synthesised kits before worker processes fork (so the sound demo runs once)."""
    for name in kits:
        if name in MODAL_KITS and name not in _KITS:
            print(f"rendering {name} one-shots with the sound service ...", flush=True)
            load_any_kit(name)


def mixed_kit(kits: tuple[str, ...], rng: np.random.Generator) -> Kit:
    """A kit whose every instrument kind comes from a kit drawn at random (kick of one, snare of another ...)."""
    loaded = [load_any_kit(n) for n in kits]
    mixed = Kit(name="mixed", licence="mixed")
    for kind in KIND_CLASS:
        having = [k for k in loaded if k.instruments.get(kind)]
        if having:
            mixed.instruments[kind] = having[int(rng.integers(len(having)))].instruments[kind]
    return mixed


def render_excerpt(job: Job) -> tuple[np.ndarray, list[Hit]]:
    """Render one job: audio (mono, SAMPLE_RATE, peak 0.9) and its hits (times from the excerpt's start)."""
    seed, path, duration, kits, dry_p = job
    rng = np.random.default_rng(seed)
    kit = load_any_kit(kits[int(rng.integers(len(kits)))])
    if len(kits) > 1 and rng.random() < MIX_P:
        kit = mixed_kit(kits, rng)
    start = float(rng.uniform(0, max(0.0, duration - EXCERPT_S)))
    notes = [Note(n.time - start + 0.2, n.pitch, n.velocity) for n in read_notes(path)
             if start <= n.time < start + EXCERPT_S]
    audio, hits = render(notes, kit, rng, duration=EXCERPT_S + 0.2, vary=rng.random() < VARY_P)
    return (augment(audio, rng) if rng.random() >= dry_p else normalise(audio)), hits


def jobs(n: int, seed: int, kits: tuple[str, ...], dry_p: float = DRY_P) -> list[Job]:
    """``n`` excerpt jobs drawn from the long (>= 20 s) Groove train-split performances."""
    files = [f for f in groove_files("train") if f[1] >= 20.0]  # long performances (beats with fills)
    rng = np.random.default_rng(seed)
    picks = rng.choice(len(files), size=n, replace=n > len(files))
    return [(seed * 100_000 + i, str(files[k][0]), files[k][1], kits, dry_p) for i, k in enumerate(picks)]


def add_arguments(ap: argparse.ArgumentParser, excerpts: int, keeps: str) -> None:
    """The options both trainers take: how many excerpts, seed, rendering processes, cache, output, the model
    file whose other part (``keeps``: 'live' or 'offline') is kept, and --retune."""
    ap.add_argument("--excerpts", type=int, default=excerpts, help=f"30-second training excerpts (default {excerpts})")
    ap.add_argument("--val-excerpts", type=int, default=150,
                    help="30-second excerpts rendered with the validation kit, to choose thresholds (default 150)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--workers", type=int, default=2, help="rendering processes (default 2)")
    ap.add_argument("--cache", type=Path, default=Path(tempfile.gettempdir()) / "batteur-recogniser-cache")
    ap.add_argument("--out", type=Path, default=MODEL_PATH)
    ap.add_argument(f"--{keeps}-from", type=Path, default=MODEL_PATH,
                    help=f"model file whose {keeps} part is kept (default: the shipped one)")
    ap.add_argument("--retune", type=Path, default=None, metavar="MODEL",
                    help="only choose the thresholds of what this trainer fits in MODEL again, on the validation kit")


def kits_installed() -> bool:
    """Whether the training and validation kits are installed (if not, says how to install them)."""
    try:
        require_kits(TRAIN_KITS + VALID_KITS)
    except KitsMissingError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return False
    return True
