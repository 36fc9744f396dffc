"""Reference band levels for test-time level matching: ``python -m services.recogniser.training.profile``.

Renders training excerpts as ``train_net --more-kits`` renders them (every fitting kit and the further acoustic
kits, 30 % left dry, instruments varied and layered), takes the long-term level of each band of each excerpt's
network input (:func:`~services.recogniser.features.band_levels`) and writes a copy of ``--model`` holding their
mean as ``offline.profile`` and ``--match`` as its ``level_match``: how far a file's level is moved towards it
before the network reads the file (docs/recogniser-history.md, "Test-time adaptation"). Nothing is fitted.
"""

from __future__ import annotations

import argparse
import signal
import sys
from pathlib import Path

import numpy as np

from common.arg_types import count, seed, unit
from common.exit_status import INTERRUPTED, report_error
from services.recogniser.errors import ModelError
from services.recogniser.features import band_levels
from services.recogniser.framenet import FrameNet
from services.recogniser.model import MODEL_PATH, load_model
from services.recogniser.training.dataset import GrooveMissingError, require_groove
from services.recogniser.training.excerpts import DRY_P, FIT_KITS, jobs, prepare, render_excerpt
from services.recogniser.training.kits import TRAIN_KITS, KitsMissingError, require_kits
from services.recogniser.training.more_kits import MORE_KITS, MoreKitsMissingError, require_more_kits
from services.recogniser.training.options import check_output, prog_of
from services.recogniser.training.soundfont import SoundfontsMissingError
from services.recogniser.transcribe import PEAK

PROG = prog_of("services.recogniser.training.profile")
"""The command's name in its usage and error lines."""
PROFILE_KITS = FIT_KITS + tuple(MORE_KITS)
"""The kits the shipped network was fitted on last (recipe 7: ``--more-kits``)."""


def reference_profile(net: FrameNet, excerpts: int, seed_: int) -> np.ndarray:
    """Mean long-term band levels (bands, input windows) of ``net``'s input over ``excerpts`` training excerpts
    (seed ``seed_``), each scaled to :data:`PEAK` as a transcribed file is."""
    prepare(PROFILE_KITS)
    levels = []
    for i, job in enumerate(jobs(excerpts, seed_, PROFILE_KITS, DRY_P, variety=True), 1):
        audio, _ = render_excerpt(job)
        levels.append(band_levels(net.spectrogram(audio * (PEAK / float(np.max(np.abs(audio)))))))
        if i % 20 == 0:
            print(f"  {i}/{excerpts} excerpts", flush=True)
    return np.mean(levels, axis=0).astype(np.float32)


def main(argv: list[str] | None = None) -> int:
    """Write the copy of ``--model`` with the profile; the exit status (README, "Exit status": 2 a bad option
    value, 1 a model file it cannot read or write or data not installed, 130 Ctrl-C with nothing written)."""
    ap = argparse.ArgumentParser(prog=PROG, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--model", type=Path, default=MODEL_PATH, help="model file to copy (default: the shipped one)")
    ap.add_argument("--out", type=Path, required=True, help="model file to write (the copy with the profile)")
    ap.add_argument("--excerpts", type=count, default=160, help="30-second training excerpts (default 160)")
    ap.add_argument("--seed", type=seed, default=1, help="seed of the excerpts (default 1, recipe 7's)")
    ap.add_argument("--match", type=unit, default=0.5,
                    help="how far (0..1) a file's level moves towards the profile's (default 0.5; 0: off)")
    args = ap.parse_args(argv)
    why = check_output(args.out)
    if why:  # a file it cannot write, not a command line it cannot run: 1
        return report_error(PROG, f"--out {args.out}: {why}")
    try:
        model = load_model(args.model)
    except ModelError as exc:
        return report_error(PROG, f"--model {exc}")
    try:
        require_kits(TRAIN_KITS)
        require_more_kits()
        require_groove(("train",))
    except (KitsMissingError, MoreKitsMissingError, SoundfontsMissingError, GrooveMissingError) as exc:
        return report_error(PROG, str(exc))
    net = model.offline
    try:
        net.profile, net.level_match = reference_profile(net, args.excerpts, args.seed), args.match
        model.save(args.out)  # whole or not at all
    except KeyboardInterrupt:
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # a second Ctrl-C must not cut the exit short (a traceback)
        print(f"{PROG}: interrupted: nothing written to {args.out}", file=sys.stderr)
        return INTERRUPTED
    except OSError as exc:  # e.g. a disk full by the time the file is written
        return report_error(PROG, f"--out {args.out}: cannot write it ({exc.strerror or exc}); nothing written")
    print(f"wrote {args.out} (level_match {args.match:g}; mean reference level {float(net.profile.mean()):.3f})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
