"""``python3 -m batteur.tools.wav_repair FILE...``: give a cut-short WAV take the length of what it holds.

Pd's ``[writesf~]`` writes a WAV header saying 0 frames when it opens a take and the real length only when the
take is closed (``/pd/stop``). A take still recording when Pd exits (``docker compose stop``, Ctrl-C, a crash)
keeps its samples but says it holds none, and players (libsndfile too) read nothing. This rewrites the RIFF and
``data`` sizes from the file's size: every whole frame written is kept (a partial last frame is dropped).

A file whose ``data`` chunk says 0 bytes is changed (the audio is taken to run from there to the end of the
file, as ``[writesf~]`` writes no chunk after it), and so is one whose file ends before the audio its header
announces (a copy or a download cut short: ``head -c``, a full disk): its header is given the whole frames it
holds. A finished take is left as it is.

RF64 files (``batteur render`` past 4 GiB) are repaired the same way: their sizes are the 64-bit ones of the
``ds64`` chunk (RIFF size, data size, sample count; EBU Tech 3306), which libsndfile leaves 0 until it closes
the file; the 32-bit sizes are set to 0xFFFFFFFF ("see ds64"), as libsndfile writes them.
"""

from __future__ import annotations

import argparse
import os
import struct
from collections.abc import Sequence
from pathlib import Path
from typing import BinaryIO

from pydantic import BaseModel

from batteur.errors import FAILED, report_error
from common.input_file import file_problem

PROG = "batteur wav-repair"
"""The command's name in its usage and error lines."""
RIFF_LIMIT_BYTES = 0xFFFFFFFF
"""A RIFF header's 32-bit sizes cannot describe more."""


class WavLayout(BaseModel):
    """Where a WAV file's audio lies, as read from its chunks (offsets and sizes in bytes)."""

    block_align: int
    """Bytes per frame (all channels)."""
    data_size_offset: int
    """Offset of the ``data`` chunk's 32-bit size field; the audio starts 4 bytes later."""
    data_size: int
    """What the ``data`` chunk says it holds (an RF64 file's: what its ``ds64`` chunk says)."""
    ds64_offset: int | None = None
    """RF64: offset of the ``ds64`` chunk's body (64-bit RIFF size, data size, sample count); None: RIFF/WAVE."""


class RepairResult(BaseModel):
    """What :func:`repair_wav` found and did."""

    repaired: bool
    frames: int
    """Frames the file holds (after the repair)."""
    dropped_bytes: int = 0
    """Bytes of a partial last frame removed."""
    header_frames: int = 0
    """Frames the header announced before the repair (0 for a take [writesf~] left open)."""
    rf64: bool = False
    """The file is RF64: its ``ds64`` sizes were the ones rewritten."""


def read_layout(f: BinaryIO) -> WavLayout:
    """The chunks of a RIFF/WAVE or RF64 file; ValueError if it is neither or has no ``fmt `` and ``data``."""
    f.seek(0)
    head = f.read(12)
    if len(head) < 12 or head[:4] not in (b"RIFF", b"RF64") or head[8:12] != b"WAVE":
        raise ValueError("not a RIFF/WAVE file")
    end = os.fstat(f.fileno()).st_size
    block_align = 0
    ds64_offset: int | None = None
    offset = 12
    while offset + 8 <= end:
        f.seek(offset)
        chunk_id, size = struct.unpack("<4sI", f.read(8))
        if chunk_id == b"ds64" and head[:4] == b"RF64":
            ds64_offset = offset + 8
        elif chunk_id == b"fmt ":
            block_align = struct.unpack("<H", f.read(16)[12:14])[0]
        elif chunk_id == b"data":
            if block_align <= 0:
                raise ValueError("no format chunk before the audio")
            if head[:4] == b"RF64":
                if ds64_offset is None:
                    raise ValueError("an RF64 file without its ds64 chunk")
                if size == RIFF_LIMIT_BYTES:  # 0xFFFFFFFF: the size is the ds64 chunk's
                    f.seek(ds64_offset + 8)
                    size = struct.unpack("<Q", f.read(8))[0]
            return WavLayout(block_align=block_align, data_size_offset=offset + 4, data_size=size,
                             ds64_offset=ds64_offset)
        offset += 8 + size + (size & 1)  # chunks are padded to an even size
    raise ValueError("no data chunk")


def write_sizes(f: BinaryIO, layout: WavLayout, data_size: int) -> None:
    """Write the sizes of a file holding ``data_size`` bytes of audio (then its pad byte) and nothing after:
    RIFF/WAVE's 32-bit RIFF and ``data`` sizes, or RF64's ``ds64`` sizes (the 32-bit ones 0xFFFFFFFF)."""
    riff_size = layout.data_size_offset + 4 + data_size + (data_size & 1) - 8
    if layout.ds64_offset is None:
        f.seek(layout.data_size_offset)
        f.write(struct.pack("<I", data_size))
        f.seek(4)
        f.write(struct.pack("<I", riff_size))
        return
    f.seek(layout.ds64_offset)
    f.write(struct.pack("<QQQ", riff_size, data_size, data_size // layout.block_align))
    f.seek(layout.data_size_offset)
    f.write(struct.pack("<I", RIFF_LIMIT_BYTES))
    f.seek(4)
    f.write(struct.pack("<I", RIFF_LIMIT_BYTES))


def repair_wav(path: Path) -> RepairResult:
    """Rewrite the sizes of a take whose header says 0 frames, or more than the file holds (see the module);
    ValueError if it cannot, without the path (as for a folder or a pipe: never opened, a pipe opened to rewrite
    waits for ever for the data it was to be read from)."""
    problem = file_problem(Path(path), "a WAV file")
    if problem is not None:
        raise ValueError(problem)
    with path.open("r+b") as f:
        layout = read_layout(f)
        rf64 = layout.ds64_offset is not None
        audio_start = layout.data_size_offset + 4
        size = os.fstat(f.fileno()).st_size
        header_frames = layout.data_size // layout.block_align
        cut_short = size - audio_start < layout.data_size
        if layout.data_size != 0 and not cut_short:  # a finished take (or not one [writesf~] left open)
            return RepairResult(repaired=False, frames=header_frames, header_frames=header_frames, rf64=rf64)
        frames = (size - audio_start) // layout.block_align
        data_size = frames * layout.block_align
        if not rf64 and audio_start + data_size + (data_size & 1) - 8 > RIFF_LIMIT_BYTES:
            raise ValueError("holds more than a WAV header can describe (4 GiB): convert it with a tool that "
                             "reads raw PCM")
        if frames == 0 and not cut_short:
            return RepairResult(repaired=False, frames=0, rf64=rf64)
        f.truncate(audio_start + data_size)  # a partial last frame is not audio
        if data_size & 1:
            f.seek(0, os.SEEK_END)
            f.write(b"\0")  # RIFF's pad byte after an odd-sized chunk
        write_sizes(f, layout, data_size)
    return RepairResult(repaired=True, frames=frames, dropped_bytes=size - audio_start - data_size,
                        header_frames=header_frames, rf64=rf64)


def unreadable(exc: OSError) -> str:
    """Why a file could not be opened, on one line without the errno."""
    if isinstance(exc, FileNotFoundError):
        return "no such file"
    if isinstance(exc, IsADirectoryError):
        return "is a folder, not a WAV file"
    if isinstance(exc, PermissionError):
        return "cannot open it to rewrite its header (permission denied)"
    return f"cannot read or rewrite it ({exc.strerror or exc})"


def describe(path: Path, result: RepairResult) -> str:
    """The line printed for a file: repaired (and from what) or left alone."""
    if not result.repaired:
        return f"{path}: left as it is ({result.frames} frames)"
    notes = ["RF64: its ds64 sizes set to the audio on disk"] if result.rf64 else []
    if result.header_frames > result.frames:
        notes.append(f"the file was cut short: its header said {result.header_frames}")
    return f"{path}: repaired, {result.frames} frames" + (f" ({'; '.join(notes)})" if notes else "")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog=PROG,
        description="Give WAV takes cut short (header saying 0 frames, e.g. a Pd take still recording when Pd "
        "exited, or more frames than the file holds, e.g. a copy cut short) the length of the audio they hold; "
        "finished files are left as they are. RF64 files (a render past 4 GiB killed while writing) are repaired "
        "alike. "
        "Exit status: 0 every file is readable now, 1 a file could not be read or repaired.")
    parser.add_argument("files", nargs="+", type=Path, metavar="FILE", help="WAV or RF64 files, e.g. out/take-*.wav")
    args = parser.parse_args(argv)
    status = 0
    for path in args.files:
        try:
            result = repair_wav(path)
        except OSError as exc:
            status = report_error(PROG, f"{path}: not repaired: {unreadable(exc)}", FAILED)
            continue
        except ValueError as exc:
            status = report_error(PROG, f"{path}: not repaired: {exc}", FAILED)
            continue
        print(describe(path, result))
    return status


if __name__ == "__main__":
    raise SystemExit(main())
