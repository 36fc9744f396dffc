"""Training excerpts: 30 s of a Groove train-split performance rendered with a (possibly mixed) kit.

Shared by both trainers (the per-candidate MLP of :mod:`.train` and the framewise
network of :mod:`.train_net`). Deterministic for a job's seed.
"""

from __future__ import annotations

import argparse
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from common.arg_types import count, seed
from common.exit_status import report_error
from services.recogniser.errors import ModelError
from services.recogniser.model import MODEL_PATH
from services.recogniser.training.dataset import GrooveMissingError, groove_files, require_groove
from services.recogniser.training.kits import (
    KIND_CLASS,
    RENDER_RATE,
    TRAIN_KITS,
    VALID_KITS,
    Instrument,
    Kit,
    KitsMissingError,
    Layer,
    load_kit,
    require_kits,
)
from services.recogniser.training.modal import MODAL_KITS, render_modal_kit
from services.recogniser.training.more_kits import FONT_KITS, MORE_KITS, load_more_kit
from services.recogniser.training.options import check_cache, check_output
from services.recogniser.training.render import Hit, Note, augment, normalise, read_notes, render
from services.recogniser.training.soundfont import SOUNDFONT_KITS, render_soundfont_kit

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

LAYER_P = {"snare": 0.35, "hh_closed": 0.35, "hh_open": 0.35, "hh_pedal": 0.35}
"""With ``variety``: chance that an instrument of a kind is layered with one of another kit (default 0.15)."""

QUIET_HIHAT_KINDS = ("hh_closed", "hh_pedal", "hh_open")
"""The kinds a quiet hi-hat lowers together (a kit whose hi-hats sound below its drums)."""
QUIET_HIHAT_DB = (6.0, 18.0)
"""Range of a quiet hi-hat's attenuation, dB (drawn uniformly)."""

Job = tuple[int, str, float, tuple[str, ...], float, bool, float, float]
"""(seed, MIDI path, performance duration s, kit names, share left dry, variety: layered instruments and the
further changes of :meth:`~.render.Variation.random_wide`, share of excerpts whose instruments are varied,
share of excerpts whose hi-hats are quiet: :func:`quiet_hihats`)."""

_KITS: dict[str, Kit] = {}


def load_any_kit(name: str) -> Kit:
    """A Hydrogen kit, one of Batteur's own synthesised kits (:data:`MODAL_KITS`), a soundfont's drum kit
    (:data:`~.soundfont.SOUNDFONT_KITS`) or a further acoustic kit (:data:`~.more_kits.MORE_KITS`), loaded once
    per process."""
    if name not in _KITS:
        if name in MODAL_KITS:
            _KITS[name] = render_modal_kit(name.removeprefix("batteur-"))
        elif name in SOUNDFONT_KITS:
            _KITS[name] = render_soundfont_kit(name)
        elif name in MORE_KITS:
            _KITS[name] = load_more_kit(name)
        else:
            _KITS[name] = load_kit(name)
    return _KITS[name]


def prepare(kits: tuple[str, ...]) -> None:
    """Make the rendered kits before worker processes fork (so each is rendered once)."""
    for name in kits:
        if (name in MODAL_KITS or name in SOUNDFONT_KITS or name in MORE_KITS) and name not in _KITS:
            how = ("the sound service" if name in MODAL_KITS
                   else "FluidSynth" if name in SOUNDFONT_KITS or name in FONT_KITS else "files")
            print(f"making {name} one-shots with {how} ...", flush=True)
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


def layered(a: Instrument, b: Instrument, rng: np.random.Generator) -> Instrument:
    """``a`` with ``b`` sounding under it: each velocity layer of ``a`` plus ``b``'s layer at the same velocity,
    brought to ``a``'s level (over the first 100 ms) times 0.3..1 and delayed by up to 1.5 ms."""
    ratio = float(rng.uniform(0.3, 1.0))
    delay = int(rng.uniform(0, 0.0015) * RENDER_RATE)
    head = int(0.1 * RENDER_RATE)
    layers = []
    for la in a.layers:
        lb = b.layer(0.5 * (la.lo + la.hi), rng)
        ra = float(np.sqrt(np.mean(la.audio[:head] ** 2)))
        rb = max(float(np.sqrt(np.mean(lb.audio[:head] ** 2))), 1e-9)
        y = np.zeros(max(len(la.audio), len(lb.audio) + delay), np.float32)
        y[: len(la.audio)] += la.audio
        y[delay : delay + len(lb.audio)] += lb.audio * (ratio * ra / rb)
        layers.append(Layer(la.lo, la.hi, la.gain, y / (1.0 + ratio)))
    return Instrument(f"{a.name} + {b.name}", a.kind, a.gain, layers)


def with_layers(kit: Kit, kits: tuple[str, ...], rng: np.random.Generator) -> Kit:
    """A copy of ``kit`` whose instruments are, each with the chance of :data:`LAYER_P`, layered with the
    same kind from another of ``kits``."""
    out = kit.copy()
    others = [load_any_kit(n) for n in kits]
    for kind, insts in kit.instruments.items():
        if not insts or rng.random() >= LAYER_P.get(kind, 0.15):
            continue
        pool = [i for k in others for i in k.instruments.get(kind, []) if all(i is not x for x in insts)]
        if pool:
            a = insts[int(rng.integers(len(insts)))]
            out.instruments[kind] = [layered(a, pool[int(rng.integers(len(pool)))], rng)]
    return out


def quiet_hihats(kit: Kit, seed: int, share: float) -> Kit:
    """``kit``, or with the chance ``share`` a copy whose hi-hats (:data:`QUIET_HIHAT_KINDS`, together) sound
    :data:`QUIET_HIHAT_DB` quieter: training excerpts like a kit whose hi-hats sit 10 dB below its drums, where
    a pedal's chick under a snare is otherwise lost. Drawn from its own generator (seeded by the job's
    ``seed``), so the rest of the excerpt is the same with and without it."""
    rng = np.random.default_rng(seed + 13_131_313)
    if share <= 0.0 or rng.random() >= share:
        return kit
    scale = float(10 ** (-rng.uniform(*QUIET_HIHAT_DB) / 20))
    out = kit.copy()
    for kind in QUIET_HIHAT_KINDS:
        if kind in out.instruments:
            out.instruments[kind] = [Instrument(i.name, i.kind, i.gain * scale, i.layers)
                                     for i in out.instruments[kind]]
    return out


def excerpt_samples() -> int:
    """Samples of one rendered excerpt."""
    return int((EXCERPT_S + 0.2) * RENDER_RATE) + 1


def render_excerpt(job: Job) -> tuple[np.ndarray, list[Hit]]:
    """Render one job: audio (mono, RENDER_RATE, peak 0.9) and its hits (times from the excerpt's start)."""
    seed, path, duration, kits, dry_p, variety, vary_p, quiet_p = job
    rng = np.random.default_rng(seed)
    kit = load_any_kit(kits[int(rng.integers(len(kits)))])
    if len(kits) > 1 and rng.random() < MIX_P:
        kit = mixed_kit(kits, rng)
    start = float(rng.uniform(0, max(0.0, duration - EXCERPT_S)))
    notes = [Note(n.time - start + 0.2, n.pitch, n.velocity) for n in read_notes(path)
             if start <= n.time < start + EXCERPT_S]
    vary = rng.random() < vary_p
    if variety and len(kits) > 1:
        kit = with_layers(kit, kits, np.random.default_rng(seed + 7_777_777))
    kit = quiet_hihats(kit, seed, quiet_p)
    audio, hits = render(notes, kit, rng, duration=EXCERPT_S + 0.2, vary=vary, wide=variety)
    return (augment(audio, rng) if rng.random() >= dry_p else normalise(audio)), hits


def jobs(n: int, seed: int, kits: tuple[str, ...], dry_p: float = DRY_P, variety: bool = False,
         vary_p: float = VARY_P, by_duration: bool = False, quiet_hihat_p: float = 0.0) -> list[Job]:
    """``n`` excerpt jobs drawn from the long (>= 20 s) Groove train-split performances (``dry_p`` = 1 and
    ``vary_p`` = 0: rendered as the benchmark renders, the kit as it is and dry).

    Each performance is equally likely, or with ``by_duration`` drawn with a probability proportional to its
    duration, so every second of them is about equally likely, as the benchmark weighs the validation split
    (its long, dense performances hold most of its strikes). A share ``quiet_hihat_p`` of the excerpts get
    quiet hi-hats (:func:`quiet_hihats`)."""
    files = [f for f in groove_files("train") if f[1] >= 20.0]  # long performances (beats with fills)
    rng = np.random.default_rng(seed)
    if by_duration:
        seconds = np.array([d for _, d in files])
        picks = rng.choice(len(files), size=n, replace=True, p=seconds / seconds.sum())
    else:
        picks = rng.choice(len(files), size=n, replace=n > len(files))
    return [(seed * 100_000 + i, str(files[k][0]), files[k][1], kits, dry_p, variety, vary_p, quiet_hihat_p)
            for i, k in enumerate(picks)]


def add_arguments(ap: argparse.ArgumentParser, excerpts: int, keeps: str) -> None:
    """The options both trainers take: how many excerpts, seed, rendering processes, cache, output, the model
    file whose other part (``keeps``: 'live' or 'offline') is kept, and --retune. Numbers are checked here, so a
    bad one is a usage error before anything is rendered."""
    ap.add_argument("--excerpts", type=count, default=excerpts,
                    help=f"30-second training excerpts, at least 1 (default {excerpts})")
    ap.add_argument("--val-excerpts", type=count, default=150,
                    help="30-second excerpts rendered with the validation kit, to choose thresholds (default 150)")
    ap.add_argument("--seed", type=seed, default=1,
                    help="random seed of the excerpts drawn and rendered (and of the fitting), 0 or more; the "
                         "validation kit's excerpts use seed + 1000 (default 1)")
    ap.add_argument("--workers", type=count, default=2, help="rendering processes (default 2)")
    ap.add_argument("--cache", type=Path, default=Path(tempfile.gettempdir()) / "batteur-recogniser-cache",
                    help="directory where rendered excerpts are kept and reused by later runs with the same "
                         "excerpts, seed and rendering options (default: %(default)s)")
    ap.add_argument("--out", type=Path, default=MODEL_PATH,
                    help="model file to write, replaced whole when the run ends (its directory must exist; "
                         "default: the shipped model, %(default)s)")
    ap.add_argument(f"--{keeps}-from", type=Path, default=MODEL_PATH,
                    help=f"model file whose {keeps} part is kept (default: the shipped one)")
    ap.add_argument("--retune", type=Path, default=None, metavar="MODEL",
                    help="only choose the thresholds of what this trainer fits in MODEL again, on the validation kit "
                         "(its strike rules too with --rules, else MODEL keeps its own)")


def check_files(args: argparse.Namespace, models: list[tuple[str, Path, Callable[[Path], object]]],
                prog: str) -> bool:
    """Whether ``args.out`` can be written, ``args.cache`` used and every model file of ``models`` (option, path,
    the reader that must accept it) read; if not, says which and why (``PROG: error: ...`` lines, ``prog`` the
    trainer's command). Checked before anything is rendered."""
    problems = [f"--out {args.out}: {why}" for why in [check_output(args.out)] if why]
    problems += [f"--cache {args.cache}: {why}" for why in [check_cache(args.cache)] if why]
    for option, path, read in models:
        try:
            read(path)
        except ModelError as exc:
            problems.append(f"{option}: {exc}")
    for problem in problems:
        report_error(prog, problem)
    return not problems


def kits_installed(prog: str) -> bool:
    """Whether the training and validation kits and the Groove MIDI Dataset are installed (if not, says how to
    install them in a ``PROG: error: ...`` line, ``prog`` the trainer's command)."""
    try:
        require_kits(TRAIN_KITS + VALID_KITS)
        require_groove(("train",))
    except (KitsMissingError, GrooveMissingError) as exc:
        report_error(prog, str(exc))
        return False
    return True


if __name__ == "__main__":  # run as a program by mistake: say which commands train
    from services.recogniser.training.options import not_a_command

    not_a_command(__spec__.name)
