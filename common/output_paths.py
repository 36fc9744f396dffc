"""Output files and directories: checked before long work starts (nothing is lost to a typo), files written whole
or not at all."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import TextIO


def check_output_dir(path: Path, option: str) -> None:
    """Raise ``ValueError`` naming ``option`` (e.g. ``-o``) when ``path`` cannot become a directory to write in:
    it exists and is not a directory, or the nearest folder that exists above it is a file or is not writable."""
    if path.exists():
        if not path.is_dir():
            raise ValueError(f"{option} {path}: exists and is not a directory")
        if not os.access(path, os.W_OK | os.X_OK):
            raise ValueError(f"{option} {path}: the directory is not writable")
        return
    first = path.absolute()  # the outermost folder to create
    while not first.parent.exists():
        first = first.parent
    above = first.parent
    if not above.is_dir():
        raise ValueError(f"{option} {path}: {above} is a file, not a directory")
    if not os.access(above, os.W_OK | os.X_OK):
        raise ValueError(f"{option} {path}: cannot create it, {above} is not writable")
    _try_mkdir(first, path, option)


def _try_mkdir(first: Path, path: Path, option: str) -> None:
    """Create ``first`` and remove it again, ``ValueError`` naming ``option`` if it cannot be: a folder may look
    writable and still refuse new entries (``/proc``, or a root process's view of some file systems)."""
    try:
        first.mkdir()
    except FileExistsError:  # made meanwhile by someone else: it is there to write in
        return
    except OSError as exc:
        raise ValueError(f"{option} {path}: cannot create a folder in {first.parent} ({exc.strerror}); choose "
                         "another place") from None
    first.rmdir()


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


def file_in_the_way(path: Path) -> Path | None:
    """The nearest existing path above ``path`` when it is not a folder (``afile`` for ``afile/x.wav``): the
    folders to create for ``path`` cannot be, as a file holds that name. None when it is a folder."""
    above = path.absolute().parent
    while not above.exists():
        above = above.parent
    return None if above.is_dir() else above


def write_atomically(path: Path, data: bytes) -> None:
    """Write ``data`` to the file ``path``: to a temporary file beside it, renamed over it, so a failed write (a
    full disk, Ctrl-C) leaves neither a partial file nor a damaged earlier one. The file keeps its permission bits,
    or gets a new file's (the temporary file's are owner-only); a symlink keeps pointing at the file it names.
    Anything not a regular file (``/dev/null``, a pipe) is written in place: renaming over it would replace it."""
    if path.exists() and not path.is_file():
        path.write_bytes(data)
        return
    target = path.resolve()
    fd, part = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".part", dir=target.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.chmod(part, _file_mode(target))
        os.replace(part, target)
    except BaseException:
        Path(part).unlink(missing_ok=True)
        raise


def _file_mode(path: Path) -> int:
    """Permission bits for a file written over ``path``: its own, or what ``open`` would give a new file."""
    if path.exists():
        return path.stat().st_mode & 0o7777
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


def point_at_devnull(stream: TextIO) -> None:
    """Point a broken output's descriptor (``| head`` gone, a closed terminal) at /dev/null, so the interpreter's
    last flush at exit stays quiet instead of failing with a BrokenPipeError."""
    try:
        fd = stream.fileno()
    except (OSError, ValueError, AttributeError):
        return
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, fd)
    os.close(devnull)
