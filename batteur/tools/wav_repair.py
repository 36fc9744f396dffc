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

A sound node's part file (``.NAME.XXXXXXXX.part``, left by a node killed or failed while recording ``NAME``;
given itself or through its folder) is made a take: its header is given every whole frame on disk (the node
keeps it up to date after each block, so at most the block being written when it was killed is missing from
it), it is renamed ``STEM-recovered.EXT`` beside it (``STEM-recovered-2.EXT`` ... if that is taken: nothing is
overwritten), and the timing the node kept beside it (``.NAME.XXXXXXXX.part.json``: the rig time of its first
sample) becomes the take's ``.json``, as a take the node named has. A part file of a take in another format
(``common.takes.TAKE_FORMATS``: W64, AIFF, CAF, AU) holds the header libsndfile kept up to date after each block
and is named as it is (at most the block being written when the node was killed is lost). A FLAC part is refused:
its length (and its last frames, still in the encoder) are written only when the node closes it, and no header
can be given to compressed audio; ``ffmpeg -i PART OUT.wav`` decodes the frames on disk, as the refusal says.
"""

from __future__ import annotations

import argparse
import fcntl
import json
import os
import shlex
import struct
from collections.abc import Sequence
from pathlib import Path
from typing import BinaryIO

from pydantic import BaseModel, Field, ValidationError

from batteur.errors import FAILED, report_error
from common.input_file import file_problem
from common.output_paths import write_atomically
from common.takes import PART_SUFFIX, TAKE_FORMATS, is_part, part_take, part_timing

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


class Recovery(BaseModel):
    """What :func:`recover_part` did with a part file."""

    take: Path
    """The file it is now (beside where the part file was)."""
    frames: int
    sample_rate_hz: int
    header_frames: int
    """Frames its header said before (fewer than ``frames``: the node was killed while writing a block)."""
    origin_rig_time_s: float | None = None
    """The rig time of its first sample, from the part's sidecar; None: the part file had none."""


def recording(part: Path) -> bool:
    """Whether a running sound node holds its lock on ``part`` (it records into it); False for one gone meanwhile
    (the node named its take) or unreadable: :func:`recover_part` says why."""
    try:
        f = part.open("rb")
    except OSError:
        return False
    with f:
        try:
            fcntl.flock(f.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return True
        except OSError:  # a file system without locks
            return False
    return False


def leftover_parts(folder: Path) -> tuple[list[Path], list[Path]]:
    """A folder's part files: (left by a node that is gone, being recorded by a running node), by name."""
    parts = sorted(p for p in folder.iterdir() if is_part(p.name) and p.is_file())
    live = [p for p in parts if recording(p)]
    return [p for p in parts if p not in live], live


def recovered_name(part: Path, take: str) -> Path:
    """``STEM-recovered.EXT`` beside ``part``, or the first of ``-2``, ``-3`` ... that names no file and no .json."""
    stem, suffix = Path(take).stem, Path(take).suffix
    n = 1
    while True:
        name = part.with_name(f"{stem}-recovered{'' if n == 1 else f'-{n}'}{suffix}")
        if not (name.exists() or name.is_symlink() or name.with_name(name.name + ".json").exists()):
            return name
        n += 1


def _audio_to_end(path: Path) -> tuple[int, int]:
    """A RIFF/WAVE or RF64 part file's header given every whole frame on disk (the node writes nothing after its
    audio); (frames before, frames now). ValueError if it is not one."""
    with path.open("r+b") as f:
        layout = read_layout(f)
        audio_start = layout.data_size_offset + 4
        size = os.fstat(f.fileno()).st_size
        before = layout.data_size // layout.block_align
        frames = (size - audio_start) // layout.block_align
        data_size = frames * layout.block_align
        if data_size == layout.data_size and size == audio_start + data_size:
            return before, frames
        if layout.ds64_offset is None and audio_start + data_size + (data_size & 1) - 8 > RIFF_LIMIT_BYTES:
            raise ValueError("holds more than a WAV header can describe (4 GiB)")
        f.truncate(audio_start + data_size)  # a partial last frame is not audio
        if data_size & 1:
            f.seek(0, os.SEEK_END)
            f.write(b"\0")
        write_sizes(f, layout, data_size)
    return before, frames


class Segment(BaseModel):
    """A stretch of the take from ``frame`` on, sample ``frame`` at rig time ``rig_time_s`` (seconds)."""

    frame: int = Field(ge=0)
    rig_time_s: float = Field(allow_inf_nan=False)


class PartTiming(BaseModel):
    """What a sound node keeps beside its part file (``.NAME.XXXX.part.json``); its other keys are ignored."""

    origin_rig_time_s: float = Field(allow_inf_nan=False)
    """Rig time of the first sample, seconds (NaN or infinite: not a node's; a take's .json never says one)."""
    segments: list[Segment] = []


def _read_timing(part: Path) -> PartTiming | None:
    """The part file's sidecar, None if it has none; ValueError if it cannot be read as one."""
    sidecar = part_timing(part)
    try:
        return PartTiming.model_validate_json(sidecar.read_bytes())
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise ValueError(f"its timing, {sidecar.name}, cannot be read ({exc.strerror or exc}): the part file is left "
                         f"as it is{WITHOUT_TIMING.format(sidecar.name)}") from None
    except ValidationError as exc:
        raise ValueError(f"its timing, {sidecar.name}, is not a sound node's ({exc.error_count()} problem(s), e.g. "
                         f"{exc.errors()[0]['msg']}): the part file is left as it is"
                         f"{WITHOUT_TIMING.format(sidecar.name)}") from None


WITHOUT_TIMING = "; delete {} and run it again to recover the audio without its rig-time origin"
"""How a part file whose timing cannot be used is recovered all the same (its sidecar's name to fill in)."""


def _decode_instead(part: Path, take_name: str) -> str:
    """How to get the frames of a part file that cannot be made a take as it is (ffmpeg reads what is on disk)."""
    out = shlex.quote(str(part.with_name(f"{Path(take_name).stem}-recovered.wav")))
    timing = part_timing(part)
    kept = f" ({timing.name} beside it holds their rig-time origin)" if timing.exists() else ""
    return f"left as it is; `ffmpeg -i {shlex.quote(str(part))} {out}` decodes the frames on disk{kept}"


def recover_part(part: Path) -> Recovery:
    """Make a node's part file a take beside it (see the module); ValueError (without the path) if it cannot:
    a live node's, one holding no audio, one that does not read as audio, a FLAC one (its length is unknown)."""
    import soundfile as sf  # only here: the header repair needs none of it

    take_name = part_take(part.name)
    if take_name is None:
        raise ValueError("not a part file a sound node left (.NAME.XXXXXXXX.part, NAME a "
                         f".{', .'.join(TAKE_FORMATS[:-1])} or .{TAKE_FORMATS[-1]})")
    problem = file_problem(part, "a part file")
    if problem is not None:
        raise ValueError(problem)
    with part.open("rb") as f:  # held while it is recovered: a node starting meanwhile finds it taken
        try:
            fcntl.flock(f.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise ValueError("a running sound node is recording into it (it names its take when it stops)") from None
        except OSError:
            pass
        head = f.read(4)
        if head == b"fLaC":  # before its timing is read: deleting that would not help
            raise ValueError("a FLAC part's length (and its last frames, still in the encoder) are written only when "
                             "the node closes it, and compressed audio cannot be given a header: "
                             + _decode_instead(part, take_name))
        timing = _read_timing(part)
        before, frames = _audio_to_end(part) if head in (b"RIFF", b"RF64") else (-1, -1)
        try:
            info = sf.info(str(part))
        except (RuntimeError, OSError) as exc:  # soundfile's LibsndfileError is a RuntimeError
            raise ValueError(f"does not read as audio ({exc})") from None
        size = os.fstat(f.fileno()).st_size
        if info.frames * info.channels > size:  # PCM holds a byte a sample at least: a header no take could have
            raise ValueError(f"its header says {info.frames} frames, more than its {size} bytes hold: "
                             + _decode_instead(part, take_name))
        if info.frames == 0:
            raise ValueError("holds no audio (the node stopped before its first block): nothing to recover")
        take = recovered_name(part, take_name)
        try:
            os.link(part, take)  # never over another file (a rename would replace one made meanwhile)
        except FileExistsError:
            raise ValueError(f"{take.name} was made meanwhile: run it again") from None
        except OSError:  # a file system without hard links: the name was free a moment ago
            os.rename(part, take)
        os.chmod(take, 0o666 & ~_umask())  # the node's part file is owner-only, as mkstemp makes it
        if timing is not None:  # the .json a take the node named has (services.sound.node.WavSink), and whence
            segments = [s.model_dump() for s in timing.segments if s.frame < info.frames and s.frame > 0]
            meta = {"origin_rig_time_s": timing.origin_rig_time_s, "sample_rate_hz": info.samplerate,
                    "channels": info.channels, "frames": info.frames,
                    "segments": [{"frame": 0, "rig_time_s": timing.origin_rig_time_s}, *segments],
                    "recovered_from": part.name}
            write_atomically(take.with_name(take.name + ".json"), json.dumps(meta, indent=2).encode("utf-8"))
        part.unlink(missing_ok=True)
        part_timing(part).unlink(missing_ok=True)
    return Recovery(take=take, frames=info.frames, sample_rate_hz=info.samplerate,
                    header_frames=before if before >= 0 else info.frames,
                    origin_rig_time_s=None if timing is None else timing.origin_rig_time_s)


def _umask() -> int:
    umask = os.umask(0)
    os.umask(umask)
    return umask


def describe_recovery(part: Path, result: Recovery) -> str:
    """The line printed for a part file made a take."""
    notes = [f"{result.frames / result.sample_rate_hz:.2f} s"]
    if result.origin_rig_time_s is not None:
        notes.append(f"rig time origin {result.origin_rig_time_s:.3f} s, in {result.take.name}.json")
    else:
        notes.append("rig time origin unknown: no timing beside it (sound nodes keep one since 7 Dec 2026)")
    if result.header_frames < result.frames:
        notes.append(f"its header said {result.header_frames} frames, now {result.frames}: killed within a block")
    return f"recovered {part} -> {result.take.name} ({'; '.join(notes)})"


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
        "A sound node's hidden part file (.NAME.XXXXXXXX.part, left by a node killed or failed while recording "
        "NAME; given itself, or its folder for every one there) is made a take beside it, STEM-recovered.EXT "
        "(-2, -3 ... if taken), its header repaired if it must be, with the .json of its rig-time origin. "
        "Exit status: 0 every file is readable now, 1 a file could not be read or repaired.")
    parser.add_argument("files", nargs="+", type=Path, metavar="FILE",
                        help="WAV or RF64 files, e.g. out/take-*.wav; a sound node's part file "
                        "(.take.wav.XXXXXXXX.part), or a folder holding some")
    args = parser.parse_args(argv)
    status = 0
    for path in args.files:
        try:
            parts = _parts_in(path) if path.is_dir() else [path] if path.name.endswith(PART_SUFFIX) else []
        except ValueError as exc:
            status = report_error(PROG, f"{path}: not repaired: {exc}", FAILED)
            continue
        except OSError as exc:
            status = report_error(PROG, f"{path}: not repaired: cannot list it ({exc.strerror or exc})", FAILED)
            continue
        for part in parts:
            try:
                print(describe_recovery(part, recover_part(part)))
            except OSError as exc:
                status = report_error(PROG, f"{part}: not recovered: {unreadable(exc)}", FAILED)
            except ValueError as exc:
                status = report_error(PROG, f"{part}: not recovered: {exc}", FAILED)
        if parts:
            continue
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


def _parts_in(folder: Path) -> list[Path]:
    """The part files a folder holds that no running node records into; [] if it holds none at all (the folder is
    then refused as a WAV file would be); ValueError if every one is being recorded."""
    left, live = leftover_parts(folder)
    if not left and live:
        raise ValueError(f"a folder whose part files ({', '.join(p.name for p in live)}) running sound nodes are "
                         "recording into (each names its take when it stops)")
    return left


if __name__ == "__main__":
    raise SystemExit(main())
