"""Train the recogniser's offline network on Groove performances rendered with the training kits.

Usage::

    nice -n 15 python -m services.recogniser.training.train_net [--excerpts 3200] [--minutes 45] [--threads 1]

Needs PyTorch (its CPU build, installed by hand: ``pip install torch==2.13.0 --index-url
https://download.pytorch.org/whl/cpu``; it is not in the 'train' extra), mir_eval and Debian's
``hydrogen-drumkits``. Bad numbers, an ``--out`` that cannot be written and unreadable model files are refused
before anything is rendered; Ctrl-C while fitting keeps the network of the lowest validation-kit loss so far
(Ctrl-C again before it is written: nothing is written); ``--out`` is replaced whole or not at all.

Renders ``--excerpts`` 30 s excerpts of Groove train-split performances with the Hydrogen training kits and
Batteur's own modal and signal synthesis (half of them on kits mixed from several; room, EQ, noise on 70 %; unless
``--plain``, layered instruments and wider per-instrument changes), fits the framewise
network (:mod:`.fit_net`) on the band spectrograms of ``--windows`` (analysis windows,
samples) and ``--bands`` (default: 44,100 Hz, 56 bands to 18 kHz; the excerpts are rendered at 44,100 Hz),
exports it to NumPy arrays and chooses its
thresholds on excerpts rendered with the validation kit (:mod:`.tune`). The held-out
kit is never used. The live classifier is copied from ``--live-from`` (made by
:mod:`.train`). Spectra are cached in ``--cache``; deterministic for a ``--seed``
(up to PyTorch's threading). ``--init MODEL`` continues fitting a model file's network (a warm start;
consider a lower ``--lr``).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from common.arg_types import count, non_negative, positive
from common.exit_status import FAILED, INTERRUPTED, report_error
from services.recogniser import features as F
from services.recogniser.classes import CLASS_NAMES
from services.recogniser.errors import ModelError
from services.recogniser.framenet import FrameNet
from services.recogniser.model import Model, load_live, load_model
from services.recogniser.training.defaults import DILATIONS, HARD_WEIGHT
from services.recogniser.training.excerpts import (
    FIT_KITS,
    VALID_DRY_P,
    VARY_P,
    add_arguments,
    check_files,
    kits_installed,
)
from services.recogniser.training.frames import (
    NEIGHBOUR_TARGET,
    ONSET_MERGE_S,
    SHORT_WINDOW,
    WINDOWS,
    CacheFullError,
    FrameSet,
    default_hop,
    make_frames,
    windows_for,
)
from services.recogniser.training.kits import VALID_KITS
from services.recogniser.training.more_kits import MORE_KITS, MoreKitsMissingError, require_more_kits
from services.recogniser.training.options import below_one, import_or_say, prog_of, save_or_say
from services.recogniser.training.soundfont import SOUNDFONT_KITS, SoundfontsMissingError, require_soundfonts

if TYPE_CHECKING:  # PyTorch and mir_eval are imported once the command line is checked (main)
    from services.recogniser.training.net import Net

PROG = prog_of("services.recogniser.training.train_net")
"""The command's name in its usage and error lines."""
NEEDS = ("torch", "services.recogniser.training.fit_net", "services.recogniser.training.net",
         "services.recogniser.training.tune")
"""The modules that fit and tune the network, imported once the command line is checked: they import PyTorch and
mir_eval, training-only dependencies that ``--help`` and the option checks do without."""
BANDS = {"narrow": F.NARROW, "wide": F.WIDE}
"""The band analyses ``--bands`` names."""
CACHE_TAG = "f4"
"""Changes when the rendering or the spectrogram change, so stale cached spectra are not reused."""


def frames(cache: Path, name: str, n: int, seed: int, workers: int, kits: tuple[str, ...], dry_p: float,
           variety: bool = False, plain: bool = False, hop: int = F.HOP, by_duration: bool = False,
           quiet_hihat_p: float = 0.0, bands: F.Bands = F.NARROW, windows_22k: tuple[int, ...] = WINDOWS) -> FrameSet:
    """The cached frame set of these excerpts, spectra of ``bands`` in the analysis windows ``windows_22k``
    (samples at 22,050 Hz), frames ``hop`` samples apart, rendered first if need be
    (``plain``: as the benchmark renders, the kit unvaried and dry, whatever ``dry_p``; ``by_duration``:
    performances drawn in proportion to their duration, :func:`.excerpts.jobs`; ``quiet_hihat_p``: the share of
    excerpts with quiet hi-hats, :func:`.excerpts.quiet_hihats`)."""
    tag = (("-variety" if variety else "") + ("-plain" if plain else "")
           + ("" if bands == F.NARROW else f"-{bands.sample_rate}hz{bands.n}")
           + (f"-hop{hop}" if hop != default_hop(bands) else "")
           + ("-bysec" if by_duration else "") + (f"-quiet{round(100 * quiet_hihat_p)}" if quiet_hihat_p else "")
           + ("" if windows_22k == WINDOWS else "-w" + "-".join(map(str, windows_22k))))
    path = cache / f"{CACHE_TAG}-{name}{tag}-{n}-{seed}.npz"
    cached = FrameSet.load_cached(path)
    if cached is not None:
        return cached
    make_frames(n, seed, workers, kits, 1.0 if plain else dry_p, variety, path, 0.0 if plain else VARY_P, hop,
                by_duration, quiet_hihat_p, bands, windows_22k)
    return FrameSet.load(path)


MEMBER_KEYS = ("excerpts", "epochs", "minutes", "width", "seed", "windows", "hard", "variety", "by_duration",
               "quiet_hihats")
"""Metadata of a trained network kept for each member of an ensemble."""


def ensemble(paths: list[Path], val: FrameSet, rules: bool = False) -> Model:
    """One model whose offline network averages the offline networks of the model files ``paths``, with
    thresholds (and with ``rules`` the strike rules, :func:`.tune.choose`) chosen on ``val``; the live MLP and the
    metadata are the first file's."""
    from services.recogniser.training.tune import choose

    models = [load_model(p) for p in paths]
    first = models[0].offline
    nets = [n for m in models for n in m.offline.networks]
    net = FrameNet(nets[0].layers, first.thresholds.copy(), first.peak_frames, first.time_offset_s, first.chord_s,
                   nets[0].windows, nets[1:], subframe=True, hop=nets[0].hop, bands=nets[0].bands)
    print(f"ensemble of {len(nets)} networks; thresholds:", flush=True)
    choose(net, val, rules=rules)
    meta = dict(models[0].meta)
    meta["ensemble_of"] = [{k: m.meta.get(k) for k in MEMBER_KEYS} | {"file": p.name}
                           for p, m in zip(paths, models, strict=True)]
    return Model(offline=net, live=models[0].live, meta=meta)


def init_net(path: Path, windows: tuple[int, ...], width: int, dilations: tuple[int, ...] = DILATIONS,
             hop: int = F.HOP, bands: F.Bands = F.NARROW, front: tuple[int, int] | None = None,
             seed: int = 0) -> Net:
    """The PyTorch form of the offline network of the model file ``path`` (analysis ``windows``, samples,
    residual ``dilations``, frames, ``hop``, samples, and the band analysis ``bands`` must be the file's), to
    continue fitting it. A time-convolution ``width`` or 2-D convolution channels ``front`` (c1, c2) larger than
    the file's grow the network with the same function (:func:`~.net.widen`); ``front`` defaults to the file's,
    or to width/8 and width/4 when the width grows; the added channels' weights are drawn from ``seed``.

    Raises ModelError (unreadable file) or ValueError (an ensemble, other windows, dilations, hop or bands, or
    a smaller width or front)."""
    from services.recogniser.training.net import from_export, widen

    offline = load_model(path).offline
    if offline.members:
        raise ValueError(f"an ensemble of {len(offline.networks)} networks; give one of its members' files")
    net = from_export(offline)
    if net.windows != windows:
        raise ValueError(f"its network reads windows {list(net.windows)}, not {list(windows)} (give --windows "
                         "to match)")
    has = (net.conv1.out_channels, net.conv2.out_channels, net.t1.out_channels)
    if front is None:
        front = (has[0], has[1]) if width == has[2] else (max(has[0], width // 8), max(has[1], width // 4))
    if width < has[2] or front[0] < has[0] or front[1] < has[1]:
        raise ValueError(f"its network has width {has[2]} and 2-D channels {has[0]} and {has[1]}: a warm start "
                         f"can keep or grow them, not shrink them to width {width} and {front[0]} and {front[1]} "
                         "(give --width and --front to match)")
    if (*front, width) != has:
        net = widen(net, front[0], front[1], width, seed)
    if net.dilations != dilations:
        raise ValueError(f"its network's dilations are {list(net.dilations)}, not {list(dilations)} "
                         "(give --dilations to match)")
    if net.hop != hop:
        raise ValueError(f"its network's frames are {net.hop} samples apart, not {hop} (give --hop to match)")
    if net.bands != bands:
        raise ValueError(f"its network reads {net.bands}, not {bands} (give --bands to match)")
    return net


def analysis_mismatch(net: FrameNet, bands: F.Bands, hop: int, rendered: tuple[int, ...]) -> str | None:
    """Why the validation excerpts rendered with ``bands``, frames ``hop`` samples apart and the analysis windows
    ``rendered`` (samples at ``bands.sample_rate``) cannot be read by the offline network ``net`` of a model file
    (to retune it or make an ensemble of it), naming the options that would match; None if they can."""
    names = {b: name for name, b in BANDS.items()}
    if net.bands != bands or net.hop != hop:
        give = (f"--bands {names[net.bands]} --hop {net.hop}" if net.bands in names
                else "a band analysis this trainer does not render")
        b = net.bands
        return (f"its network reads {b.n} bands to {b.f_max_hz:.0f} Hz at {b.sample_rate} Hz, frames {net.hop} "
                f"samples apart (give {give})")
    unread = sorted(set(net.inputs) - set(rendered))
    if unread:
        return f"its network reads analysis windows {unread} samples long, which are not rendered (give --windows)"
    return None


def output_weights(items: list[str]) -> dict[int, float]:
    """``NAME=W`` items (a class name or 'onset') as {activation index: loss weight}; raises ValueError."""
    names = [*CLASS_NAMES, "onset"]
    out: dict[int, float] = {}
    for item in items:
        name, _, w = item.partition("=")
        if name not in names or not w:
            raise ValueError(f"{item!r}: give NAME=WEIGHT with NAME one of {', '.join(names)}")
        value = float(w)
        if not 0.0 <= value < float("inf"):  # also NaN: a loss weighted by it is NaN, the network fitted useless
            raise ValueError(f"{item!r}: the weight must be a finite number of at least 0")
        out[names.index(name)] = value
    return out


def build_parser() -> argparse.ArgumentParser:
    """The trainer's command line (numbers checked as they are parsed)."""
    ap = argparse.ArgumentParser(prog=PROG, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_arguments(ap, excerpts=3200, keeps="live")
    ap.add_argument("--epochs", type=positive, default=5.0, help="passes over the training frames (default 5)")
    ap.add_argument("--minutes", type=positive, default=None,
                    help="stop the fitting earlier to take about this long (the learning rate schedule follows; "
                         "Ctrl-C also stops it, keeping the network of the lowest validation-kit loss so far)")
    ap.add_argument("--width", type=int, default=128,
                    help="channels of the network's time convolutions (the 2-D ones have 1/8 and 1/4 of it unless "
                         "--front; with --init, a width above the file's grows its network, computing the same "
                         "function at the start)")
    ap.add_argument("--front", type=int, nargs=2, default=None, metavar=("C1", "C2"),
                    help="channels of the network's two 2-D convolutions (default: width/8 and width/4; with "
                         "--init, the file's unless the width grows; larger than the file's grows them)")
    ap.add_argument("--dilations", type=int, nargs="+", default=list(DILATIONS), metavar="D",
                    help="dilations of the residual time convolutions, frames (kernel 3: the context each side is "
                         f"3 + their sum frames of 10 ms; default {' '.join(map(str, DILATIONS))})")
    ap.add_argument("--bands", choices=sorted(BANDS), default="wide",
                    help="the network's band analysis: 'wide', 44,100 Hz, 56 bands to 18 kHz, where hi-hats are "
                         "heard above snares (default, recipe 5); 'narrow', 22,050 Hz, 48 bands to 10.5 kHz "
                         "(recipes 3 and 4)")
    ap.add_argument("--hop", type=int, default=None,
                    help="samples at the band analysis's rate between the network's frames (default: 10 ms, 220 "
                         "at 22,050 Hz, 441 at 44,100 Hz; 110 at 22,050 Hz: 5 ms, twice the frames, so strikes "
                         "20-30 ms apart are 4-6 frames apart; the dilations count frames, so double them to keep "
                         "the context in seconds)")
    ap.add_argument("--threads", type=count, default=2, help="PyTorch threads (default 2)")
    ap.add_argument("--windows", type=int, nargs="+", default=list(WINDOWS), choices=(SHORT_WINDOW, *WINDOWS),
                    help="analysis windows of the network's input spectrograms, samples at 22,050 Hz (12, 23, 46, 93 "
                         "ms; the wide bands' windows last as long; default: 512 1024 2048; with 256 the frame sets "
                         "are rendered with it too)")
    ap.add_argument("--hard", type=non_negative, default=HARD_WEIGHT,
                    help="extra loss weight of a class's negatives where another class is struck "
                         f"(default {HARD_WEIGHT})")
    ap.add_argument("--weight", nargs="+", default=[], metavar="NAME=W",
                    help="loss weight of a class's activation or of the onset output (e.g. snare=2; default 1)")
    ap.add_argument("--neighbour-target", type=float, default=NEIGHBOUR_TARGET, metavar="T",
                    help="target of the frames beside a strike's frame, 0..1 (lower: sharper peaks, so strikes "
                         f"20-30 ms apart can give two; default {NEIGHBOUR_TARGET})")
    ap.add_argument("--onset-merge", type=float, default=None, metavar="S",
                    help="train the onset output on onsets rather than strikes: strikes within S seconds of an "
                         f"onset's first strike are that onset, as the benchmark counts onsets ({ONSET_MERGE_S}); "
                         "default: every strike is an onset")
    ap.add_argument("--plain", action="store_true",
                    help="render without layered instruments and the wider per-instrument changes (recipe 3's data)")
    ap.add_argument("--val-plain", action="store_true",
                    help="render the validation-kit excerpts the thresholds are chosen on as the benchmark renders: "
                         "the kit as it is (no per-instrument changes) and dry")
    ap.add_argument("--rules", action="store_true",
                    help="also choose on the validation kit how far class strikes move to onset-output peaks and the "
                         "ratio that drops snare peaks under hi-hat peaks (FrameNet.snap_frames, hihat_snare)")
    ap.add_argument("--soundfonts", action="store_true",
                    help="also fit on the drum kits of General MIDI soundfonts rendered by FluidSynth "
                         "(training/soundfont.py; Debian packages fluidsynth, fluid-soundfont-gm, "
                         "musescore-general-soundfont-small, timgm6mb-soundfont)")
    ap.add_argument("--more-kits", action="store_true",
                    help="also fit on two further recorded acoustic kits: Sonic Pi's and AVL's Red Zeppelin without "
                         "its hi-hats (training/more_kits.py; Debian packages sonic-pi-samples, "
                         "avldrums.lv2-soundfont, fluidsynth)")
    ap.add_argument("--by-duration", action="store_true",
                    help="draw the excerpts' performances (training and validation kit) in proportion to their "
                         "duration, so every second is about equally likely, as the benchmark weighs the split "
                         "(default: every performance equally likely)")
    ap.add_argument("--quiet-hihats", type=float, default=0.0, metavar="P",
                    help="share of training excerpts (0..1) whose hi-hats, pedal included, sound 6-18 dB quieter "
                         "than the kit's (as in a kit whose hi-hats sit below its drums; default 0)")
    ap.add_argument("--val-quiet-hihats", type=float, default=0.0, metavar="P",
                    help="the same for the validation kit's excerpts, so thresholds are chosen where a quiet hi-hat "
                         "is hard to hear too (default 0)")
    ap.add_argument("--render-only", action="store_true", help="render (and cache) the excerpts, do not fit")
    ap.add_argument("--ensemble", type=Path, nargs="+", default=None, metavar="MODEL",
                    help="only average the offline networks of these model files into one (the live MLP and metadata "
                         "of the first) and choose its thresholds on the validation kit")
    ap.add_argument("--half", action="store_true", help="store the offline network's weights as float16")
    ap.add_argument("--init", type=Path, default=None, metavar="MODEL",
                    help="continue fitting the offline network of this model file (its windows, dilations, hop "
                         "and bands must be those given; --width and --front may grow it)")
    ap.add_argument("--lr", type=positive, default=2e-3, help="peak learning rate (default 2e-3)")
    ap.add_argument("--warmup", type=below_one, default=0.03,
                    help="share of the run over which the learning rate rises to its peak, 0 up to 1 "
                         "(default 0.03)")
    return ap


def main(argv: list[str] | None = None) -> int:
    """Train what the command line asks for; the exit status (README, "Exit status": 2 a bad option value, 1 a
    file it cannot use, data not installed or a fitting that failed, 130 Ctrl-C)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    problem = option_problem(args)
    if problem:  # before any file is read: a command line that cannot run
        parser.error(problem)
    if not import_or_say(NEEDS, PROG):  # PyTorch or mir_eval not installed: said what to install
        return FAILED
    models: list[tuple[str, Path, Callable[[Path], object]]] = [("--live-from", args.live_from, load_live)]
    models += [(option, path, load_model) for option, path in  # also refuses NaN weights
               [("--retune", args.retune), ("--init", args.init)] if path is not None]
    models += [("--ensemble", p, load_model) for p in args.ensemble or []]
    if not check_files(args, models, PROG) or not kits_installed(PROG):
        return FAILED
    try:
        return run(args)
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted: nothing written to {args.out} (sets of excerpts rendered in full are kept in "
              f"{args.cache} for the next run)", file=sys.stderr)
        return INTERRUPTED
    except CacheFullError as exc:
        return report_error(PROG, f"{exc}; nothing written to {args.out}")


def option_problem(args: argparse.Namespace) -> str | None:
    """What is wrong with the values of the parsed options ``args`` that their types do not check (ranges that
    depend on the option), or None."""
    try:
        output_weights(args.weight)
    except ValueError as exc:
        return f"--weight {exc}"
    if args.onset_merge is not None and not 0.0 <= args.onset_merge <= 0.1:
        return f"--onset-merge must be within 0..0.1 s, got {args.onset_merge}"
    if not 0.0 <= args.neighbour_target <= 1.0:
        return f"--neighbour-target must be within 0..1, got {args.neighbour_target}"
    for flag, share in (("--quiet-hihats", args.quiet_hihats), ("--val-quiet-hihats", args.val_quiet_hihats)):
        if not 0.0 <= share <= 1.0:
            return f"{flag} must be within 0..1, got {share}"
    if args.hop is not None and not F.HOP_RANGE[0] <= args.hop <= F.HOP_RANGE[1]:  # None: the bands' default
        return f"--hop must be {F.HOP_RANGE[0]}..{F.HOP_RANGE[1]} samples, got {args.hop}"
    if min(args.dilations) < 1:
        return f"--dilations must be positive frame counts, got {args.dilations}"
    if args.width < 8 or (args.front is not None and min(args.front) < 1):
        return f"--width must be at least 8 and --front positive, got {args.width} and {args.front}"
    return None


def run(args: argparse.Namespace) -> int:
    """Render, fit, tune and write what the checked command line ``args`` asks for."""
    from services.recogniser.training.tune import choose

    fit_kits = FIT_KITS
    if args.soundfonts:
        try:
            require_soundfonts(list(SOUNDFONT_KITS))
        except SoundfontsMissingError as exc:
            return report_error(PROG, str(exc))
        fit_kits = FIT_KITS + tuple(SOUNDFONT_KITS)
    if args.more_kits:
        try:
            require_more_kits()
        except (MoreKitsMissingError, SoundfontsMissingError) as exc:
            return report_error(PROG, str(exc))
        fit_kits = fit_kits + tuple(MORE_KITS)
    bands = BANDS[args.bands]
    windows = windows_for(bands, tuple(sorted(set(args.windows))))
    rendered = (SHORT_WINDOW, *WINDOWS) if SHORT_WINDOW in args.windows else WINDOWS  # windows in the frame sets
    args.hop = default_hop(bands) if args.hop is None else args.hop
    weights = output_weights(args.weight)  # checked by option_problem
    for option, path in [("--retune", args.retune)] * (args.retune is not None) + [("--ensemble", p)
                                                                                  for p in args.ensemble or []]:
        why = analysis_mismatch(load_model(path).offline, bands, args.hop, windows_for(bands, rendered))
        if why:  # found now, not once the validation excerpts are rendered
            return report_error(PROG, f"{option} {path}: {why}")
    init = None
    if args.init is not None:
        try:
            init = init_net(args.init, windows, args.width, tuple(args.dilations), args.hop, bands,
                            None if args.front is None else (args.front[0], args.front[1]), args.seed)
        except (ModelError, ValueError) as exc:
            return report_error(PROG, f"--init {args.init}: {exc}")
    t0 = time.time()
    val = frames(args.cache, "val", args.val_excerpts, args.seed + 1000, args.workers, VALID_KITS, VALID_DRY_P,
                 plain=args.val_plain, hop=args.hop, by_duration=args.by_duration, quiet_hihat_p=args.val_quiet_hihats,
                 bands=bands, windows_22k=rendered)
    if args.retune is not None:
        model = load_model(args.retune)
        choose(model.offline, val, rules=args.rules)
        model.meta.update(val_plain=args.val_plain, rules=args.rules, val_quiet_hihats=args.val_quiet_hihats)
        if save_or_say(model, args.out, PROG, half=args.half) is None:
            return FAILED
        print(f"wrote {args.out}")
        return 0
    if args.ensemble:
        size = save_or_say(ensemble(args.ensemble, val, args.rules), args.out, PROG, half=args.half)
        if size is None:
            return FAILED
        print(f"wrote {args.out} ({size / 1024:.0f} KiB)")
        return 0
    live, live_meta = load_live(args.live_from)
    train = frames(args.cache, "train" + ("-sf" if args.soundfonts else "") + ("-mk" if args.more_kits else ""),
                   args.excerpts, args.seed, args.workers,
                   fit_kits, 0.3, not args.plain, hop=args.hop, by_duration=args.by_duration,
                   quiet_hihat_p=args.quiet_hihats, bands=bands, windows_22k=rendered)
    if args.render_only:
        return 0
    import torch  # here: retuning and ensembles do without it (the tests run them without PyTorch)

    from services.recogniser.training.fit_net import FitError, fit
    from services.recogniser.training.net import export

    torch.set_num_threads(args.threads)
    print(f"training: {train.n_excerpts} excerpts, {len(train.spec)} frames, {len(train.hits)} strikes; "
          f"validation kit: {val.n_excerpts} excerpts; {time.time() - t0:.0f} s", flush=True)
    front = None if args.front is None else (args.front[0], args.front[1])
    try:
        fitted = fit(train, val, args.epochs, args.seed, lr=args.lr, minutes=args.minutes, width=args.width,
                     front=front, windows=windows, hard=args.hard, init=init, warmup=args.warmup,
                     outputs=weights, neighbour=args.neighbour_target, dilations=tuple(args.dilations),
                     onset_merge_s=args.onset_merge)
    except FitError as exc:  # no state whose loss is a number
        return report_error(PROG, f"{exc}; nothing written to {args.out}")
    net = export(fitted)
    print("thresholds:", flush=True)
    choose(net, val, rules=args.rules)
    meta = {"trained_on": list(fit_kits), "thresholds_from": list(VALID_KITS), "excerpts": args.excerpts,
            "val_excerpts": args.val_excerpts, "val_plain": args.val_plain, "rules": args.rules,
            "epochs": args.epochs, "minutes": args.minutes, "width": args.width,
            "front": [init.conv1.out_channels, init.conv2.out_channels] if init is not None
            else args.front or [args.width // 8, args.width // 4], "dilations": args.dilations,
            "seed": args.seed, "windows": list(windows), "hard": args.hard, "variety": not args.plain,
            "neighbour_target": args.neighbour_target, "onset_merge_s": args.onset_merge, "hop": args.hop,
            "bands": args.bands,
            "by_duration": args.by_duration,
            "quiet_hihats": args.quiet_hihats, "val_quiet_hihats": args.val_quiet_hihats,
            "weights": {([*CLASS_NAMES, "onset"])[k]: w for k, w in weights.items()},
            "lr": args.lr, "warmup": args.warmup, "init": None if args.init is None else args.init.name,
            # where the live MLP came from (a file of this format already records it as live_*)
            "live_trained_on": live_meta.get("live_trained_on", live_meta.get("trained_on", [])),
            "live_excerpts": live_meta.get("live_excerpts", live_meta.get("excerpts")),
            "data": "Groove MIDI Dataset train split (CC BY 4.0) rendered with hydrogen-drumkits and Batteur's "
                    "synthesis" + (" and General MIDI soundfonts' drum kits" if args.soundfonts else "")
                    + (", Sonic Pi's drum samples (CC0) and AVL's Red Zeppelin kit (CC-BY-SA-3.0)"
                       if args.more_kits else "")}
    size = save_or_say(Model(offline=net, live=live, meta=meta), args.out, PROG, half=args.half)
    if size is None:  # e.g. a disk full by the end of the run
        return FAILED
    print(f"wrote {args.out} ({size / 1024:.0f} KiB) in {time.time() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
