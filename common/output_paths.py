"""Checks that an output directory or file can be written before long work starts (nothing is lost to a typo)."""

from __future__ import annotations

import os
from pathlib import Path


def check_output_dir(path: Path, option: str) -> None:
    """Raise ``ValueError`` naming ``option`` (e.g. ``-o``) when ``path`` cannot become a directory to write in:
    it exists and is not a directory, or the nearest folder that exists above it is a file or is not writable."""
    if path.exists():
        if not path.is_dir():
            raise ValueError(f"{option} {path}: exists and is not a directory")
        if not os.access(path, os.W_OK | os.X_OK):
            raise ValueError(f"{option} {path}: the directory is not writable")
        return
    above = path.absolute().parent
    while not above.exists():
        above = above.parent
    if not above.is_dir():
        raise ValueError(f"{option} {path}: {above} is a file, not a directory")
    if not os.access(above, os.W_OK | os.X_OK):
        raise ValueError(f"{option} {path}: cannot create it, {above} is not writable")


def check_output_file(path: Path, option: str) -> None:
    """Raise ``ValueError`` naming ``option`` when the file ``path`` cannot be written: it is a directory, or its
    folder does not exist or is not writable."""
    if path.is_dir():
        raise ValueError(f"{option} {path}: is a directory, not a file")
    folder = path.absolute().parent
    if folder.exists() and not folder.is_dir():
        raise ValueError(f"{option} {path}: {folder} is a file, not a folder")
    if not folder.is_dir():
        raise ValueError(f"{option} {path}: folder {folder} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise ValueError(f"{option} {path}: folder {folder} is not writable")
