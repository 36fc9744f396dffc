"""What the trainers' command lines check before any rendering or fitting, and how they write a model file.

A training run renders for minutes and fits for up to an hour: a bad number, an output directory that does not
exist or an unreadable model file must stop it at once with a one-line error, not after the work is done. The
model file is written whole or not at all (a Ctrl-C or a full disk while writing leaves an earlier file as it
was).
"""

from __future__ import annotations

import argparse
import importlib
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

from common.arg_types import number
from common.exit_status import USAGE, report_error
from services.recogniser.model import Model

INSTALL = {
    "torch": "PyTorch is needed to fit the network: install its CPU build with `pip install torch==2.13.0 "
             "--index-url https://download.pytorch.org/whl/cpu` (it is not in the 'train' extra; "
             "docs/recogniser.md)",
    "sklearn": "scikit-learn is needed to fit the live classifier: install the 'train' extra with "
               "`pip install -e '.[train]'`",
    "mir_eval": "mir_eval is needed to choose the thresholds: `pip install mir_eval` (it is in the 'test' extra: "
                "`pip install -e '.[test]'`)",
}
"""How to install each optional module a trainer imports (named by its top-level module)."""


def prog_of(module: str) -> str:
    """The command that runs ``module`` (``python -m MODULE``): the name its usage and error lines start with."""
    return f"python -m {module}"


def missing_dependency(exc: ModuleNotFoundError, prog: str) -> str:
    """The one-line error (``PROG: error: ...``) of the trainer ``prog`` whose optional module is not installed,
    naming what to install; exit status 1 (README, "Exit status": the installation's fault, not the command
    line's)."""
    top = (exc.name or "").split(".")[0]
    return f"{prog}: error: {INSTALL.get(top, f'the Python module {top!r} is not installed ({exc})')}"


def import_or_say(modules: Sequence[str], prog: str) -> bool:
    """Import ``modules`` (a trainer's training-only dependencies, or its modules that import them), once its
    command line is checked: ``--help`` and a refused option do without them. False after saying what to install
    (:func:`missing_dependency`) if one is not installed."""
    try:
        for module in modules:
            importlib.import_module(module)
    except ModuleNotFoundError as exc:
        print(missing_dependency(exc, prog), file=sys.stderr)
        return False
    return True


def below_one(text: str) -> float:
    """A share from 0 up to, not including, 1 (the learning rate's warm-up: the decay after it needs some run)."""
    value = number(text)
    if not 0.0 <= value < 1.0:
        raise argparse.ArgumentTypeError(f"{text!r}: give a share from 0 up to (not including) 1")
    return value


def check_output(path: Path) -> str | None:
    """Why a model file cannot be written at ``path`` (its directory missing, not a directory or not writable,
    or ``path`` a directory), or None. Tried by creating and removing a file beside it."""
    parent = path.parent
    if path.is_dir():
        return f"{path} is a directory; give a file name such as {path / 'recogniser.npz'}"
    if not parent.is_dir():
        return f"{parent} is not a directory (create it first)"
    try:
        with tempfile.NamedTemporaryFile(dir=parent, prefix=f".{path.name}.", suffix=".check"):
            pass
    except OSError as exc:
        return f"cannot write in {parent}: {exc.strerror or exc}"
    return None


def check_cache(path: Path) -> str | None:
    """Why the cache directory ``path`` cannot be made and written, or None (made if need be)."""
    try:
        path.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=path, suffix=".check"):
            pass
    except OSError as exc:
        return f"cannot use {path} as the cache: {exc.strerror or exc}"
    return None


def save_model(model: Model, path: Path, half: bool = False) -> int:
    """Write ``model`` to exactly ``path``, whole or not at all (:meth:`Model.save`). Returns the file's size,
    bytes."""
    model.save(path, half=half)
    return path.stat().st_size


def save_or_say(model: Model, path: Path, prog: str, half: bool = False) -> int | None:
    """:func:`save_model` at the end of a run, or None after saying it could not (``PROG: error: --out PATH:
    cannot write it (REASON); nothing written``; exit status 1): ``--out`` was checked at the start, but a disk
    may fill or a folder go away while the run renders and fits."""
    try:
        return save_model(model, path, half=half)
    except OSError as exc:
        report_error(prog, f"--out {path}: cannot write it ({exc.strerror or exc}); nothing written")
        return None


COMMANDS = ("services.recogniser.training.train_net", "services.recogniser.training.train")
"""The trainers' commands: the offline network's and the live classifier's."""


def not_a_command(module: str) -> None:
    """Exit 2 saying that ``module``, run as a program, is a part of the trainers (rather than do nothing and
    exit 0, as if it had worked)."""
    print(f"{prog_of(module)}: error: {module} is a part of the trainers, not a command: run "
          f"{prog_of(COMMANDS[0])} (the offline network) or {prog_of(COMMANDS[1])} (the live classifier); --help "
          "lists their options", file=sys.stderr)
    raise SystemExit(USAGE)
