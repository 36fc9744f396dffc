"""Train the recogniser's offline network on Groove performances rendered with the training kits.

Usage::

    nice -n 15 python -m services.recogniser.training.train_net [--excerpts 1600] [--epochs 3] [--workers 2]

Needs PyTorch (CPU; training only: ``pip install -e '.[train]'``) and Debian's
``hydrogen-drumkits``. Renders ``--excerpts`` 30 s excerpts of Groove train-split
performances with the Hydrogen training kits and Batteur's own modal and signal
synthesis (half of them on kits mixed from several; room, EQ, noise on 70 %), fits
the framewise network (:mod:`.fit_net`), exports it to NumPy arrays and chooses its
thresholds on excerpts rendered with the validation kit (:mod:`.tune`). The held-out
kit is never used. The live classifier is copied from ``--live-from`` (made by
:mod:`.train`). Spectra are cached in ``--cache``; deterministic for a ``--seed``
(up to PyTorch's threading).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import torch

from services.recogniser.model import Model, load_live, load_model
from services.recogniser.training.excerpts import FIT_KITS, VALID_DRY_P, add_arguments, kits_installed
from services.recogniser.training.fit_net import fit
from services.recogniser.training.frames import FrameSet, make_frames
from services.recogniser.training.kits import VALID_KITS
from services.recogniser.training.net import export
from services.recogniser.training.tune import choose

CACHE_TAG = "f2"
"""Changes when the rendering or the spectrogram change, so stale cached spectra are not reused."""


def frames(cache: Path, name: str, n: int, seed: int, workers: int, kits: tuple[str, ...], dry_p: float) -> FrameSet:
    path = cache / f"{CACHE_TAG}-{name}-{n}-{seed}.npz"
    if path.exists():
        return FrameSet.load(path)
    data = make_frames(n, seed, workers, kits, dry_p)
    data.save(path)
    return data


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_arguments(ap, excerpts=3200, keeps="live")
    ap.add_argument("--epochs", type=float, default=5.0, help="passes over the training frames (default 5)")
    ap.add_argument("--minutes", type=float, default=None,
                    help="stop the fitting earlier to take about this long (the learning rate schedule follows)")
    ap.add_argument("--width", type=int, default=128,
                    help="channels of the network's time convolutions (the 2-D ones have 1/8 and 1/4 of it)")
    ap.add_argument("--threads", type=int, default=2, help="PyTorch threads (default 2)")
    args = ap.parse_args(argv)
    if not kits_installed():
        return 1
    torch.set_num_threads(args.threads)
    args.cache.mkdir(parents=True, exist_ok=True)
    t0 = time.time()
    val = frames(args.cache, "val", args.val_excerpts, args.seed + 1000, args.workers, VALID_KITS, VALID_DRY_P)
    if args.retune is not None:
        model = load_model(args.retune)
        choose(model.offline, val)
        model.save(args.out)
        print(f"wrote {args.out}")
        return 0
    live, live_meta = load_live(args.live_from)
    train = frames(args.cache, "train", args.excerpts, args.seed, args.workers, FIT_KITS, 0.3)
    print(f"training: {train.n_excerpts} excerpts, {len(train.spec)} frames, {len(train.hits)} strikes; "
          f"validation kit: {val.n_excerpts} excerpts; {time.time() - t0:.0f} s", flush=True)
    net = export(fit(train, val, args.epochs, args.seed, minutes=args.minutes, width=args.width))
    print("thresholds:", flush=True)
    choose(net, val)
    meta = {"trained_on": list(FIT_KITS), "thresholds_from": list(VALID_KITS), "excerpts": args.excerpts,
            "val_excerpts": args.val_excerpts, "epochs": args.epochs, "minutes": args.minutes, "width": args.width,
            "seed": args.seed,
            # where the live MLP came from (a file of this format already records it as live_*)
            "live_trained_on": live_meta.get("live_trained_on", live_meta.get("trained_on", [])),
            "live_excerpts": live_meta.get("live_excerpts", live_meta.get("excerpts")),
            "data": "Groove MIDI Dataset train split (CC BY 4.0) rendered with hydrogen-drumkits and Batteur's "
                    "synthesis"}
    Model(offline=net, live=live, meta=meta).save(args.out)
    print(f"wrote {args.out} ({args.out.stat().st_size / 1024:.0f} KiB) in {time.time() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
