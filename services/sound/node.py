"""The sound node: :class:`~services.sound.core.SoundCore` live over UDP, to the sound card and/or a WAV file.

    batteur sound --wav take.wav                      # record what the rig plays
    batteur sound --latency-s 0.03 --model sample     # lower latency, sampled kit

The node steps the core at its block rate (48 kHz / 256 = 187.5 Hz) on the
rig clock, so each step renders the blocks that are due. Output goes to the
sound card only when portaudio reports a device (checked first: booting
portaudio without a device crashes the interpreter) and ``--device`` is not
``none``; to a WAV file with ``--wav``. With neither, the node still
schedules and renders (useful for testing and for counting late strikes).
"""

from __future__ import annotations

import argparse
import collections
import fcntl
import glob
import json
import logging
import os
import string
import tempfile
import threading
from collections.abc import Callable, Sequence
from datetime import datetime
from pathlib import Path
from typing import Any, Literal

import numpy as np
import numpy.typing as npt
import soundfile as sf
from pydantic import Field, field_validator

from common.config import NodeSettings
from common.exit_status import InputError
from common.kit import Kit, load_kit
from common.messages import OscMessage
from common.output_paths import check_output_file, file_in_the_way, write_atomically
from common.runtime import Node, run_node
from common.takes import PART_SUFFIX, TAKE_FORMATS, is_part, part_prefix, part_timing, parts_glob
from services.sound.core import MAX_LATENCY_S, WAV_LIMIT_BYTES, SoundCore, SoundSettings, wav_format
from services.sound.params_file import (
    apply_sound_params,
    check_against_kit,
    check_params_out,
    load_sound_params,
    settle_rebuilds,
    write_sound_params,
)
from services.sound.pyo_stage import _quiet_stderr, audio_device_count, import_pyo

log = logging.getLogger("batteur.sound")


HORIZON_S = 10.0
"""Impacts due more than this many seconds after the sound being rendered are dropped (a sender's clock error:
impacts are sent as they happen, so a live one is due within the latency window)."""
MAX_PENDING = 4096
"""Impacts waiting for their block at most (far more than 10 s of drumming), so a flood cannot fill memory."""


SFC_SET_UPDATE_HEADER_AUTO = 0x1061
"""libsndfile command (sndfile.h): rewrite the header's lengths after every write."""
SFC_RF64_AUTO_DOWNGRADE = 0x1210
"""libsndfile command (sndfile.h): an RF64 file is written with a plain RIFF/WAVE header (and a JUNK chunk that
reserves room for RF64's ds64) for as long as it stays under 4 GiB, and switches to RF64 beyond."""


START_PLACEHOLDER = "{start}"
"""In ``--wav``'s file name: the take's start time, local, as :data:`START_FORMAT` (once, when recording starts)."""
START_FORMAT = "%Y%m%d-%H%M%S"


def wav_name_has_start(path: Path) -> bool:
    """Whether ``path``'s file name holds ``{start}``; ValueError for any other placeholder or a lone brace.

    The file name is read as a :meth:`str.format` string (``{{`` and ``}}`` for a brace); the folders are taken
    as written, so the rig's ``--record DIR`` may hold any character.
    """
    try:
        parts = list(string.Formatter().parse(path.name))
    except ValueError as exc:  # "Single '}' encountered in format string"
        raise ValueError(f"--wav {path}: {exc} in the file name (a brace is written {{{{ or }}}})") from None
    fields = [(name, conversion, spec) for _, name, spec, conversion in parts if name is not None]
    for name, conversion, spec in fields:
        if (name, conversion, spec) != ("start", None, ""):
            shown = "{" + name + (f"!{conversion}" if conversion else "") + (f":{spec}" if spec else "") + "}"
            raise ValueError(f"--wav {path}: unknown placeholder {shown}: the only one is {START_PLACEHOLDER}, "
                             "the take's start time")
    return bool(fields)


def expand_wav_path(path: Path, now: datetime) -> Path:
    """The file ``--wav`` names for a take starting at ``now`` (local time).

    Without ``{start}`` that is ``path`` itself, replaced at the end as always. With it, the first of
    ``NAME``, ``NAME-2``, ``NAME-3`` ... (before the extension) that no take holds yet: no file, no ``.json``
    and no part file of a node still recording it, so two takes in the same second are both kept.
    """
    if "{" not in path.name and "}" not in path.name:
        return path
    name = path.name.format(start=now.strftime(START_FORMAT))
    if not wav_name_has_start(path):
        return path.with_name(name)  # only escaped braces
    stem, suffix = Path(name).stem, Path(name).suffix
    candidate, n = path.with_name(name), 1
    while _taken(candidate):
        n += 1
        candidate = path.with_name(f"{stem}-{n}{suffix}")
    return candidate


def _taken(path: Path) -> bool:
    """A take is, or is being, written at ``path`` (see :class:`WavSink`'s part and .json files)."""
    parts = glob.glob(os.path.join(glob.escape(str(path.parent)), parts_glob(path.name)))
    return path.exists() or path.is_symlink() or path.with_name(path.name + ".json").exists() or bool(parts)


def in_use(part: Path) -> bool:
    """Whether a running node is recording into ``part`` (it holds a lock on it, released however it ends: SIGKILL
    too); False when that cannot be told (no such file: nobody writes it)."""
    try:
        fd = os.open(part, os.O_RDONLY)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    except OSError:  # a file system without locks: taken as left over (wav-repair checks again)
        return False
    finally:
        os.close(fd)  # releases the lock taken just above
    return False


def leftover_parts(folder: Path, own: Path | None = None) -> list[Path]:
    """The take part files in ``folder`` that no running node records into (a node killed, or that failed, left
    them), ``own`` aside, by name."""
    try:
        names = sorted(p for p in folder.iterdir() if is_part(p.name))
    except OSError:
        return []
    return [p for p in names if p != own and p.is_file() and not in_use(p)]


def say_leftover_parts(folder: Path, own: Path | None) -> None:
    """At start: a take left unnamed in the take's folder by an earlier node (killed, or failed) is hidden there
    (a dot file): say it once, with the command that makes it a take with its timing."""
    left = leftover_parts(folder, own)
    if not left:
        return
    shown = ", ".join(p.name for p in left[:3]) + (f" and {len(left) - 3} more" if len(left) > 3 else "")
    what = "a take" if len(left) == 1 else f"{len(left)} takes"
    log.warning("%s left unnamed by an earlier sound node that did not stop cleanly (killed or failed) in %s: %s; "
                "`batteur wav-repair %s` names %s (NAME-recovered.wav) and keeps %s rig-time origin in its .json",
                what, folder, shown, left[0] if len(left) == 1 else folder, "it" if len(left) == 1 else "each",
                "its" if len(left) == 1 else "their")


class WavSink:
    """Appends blocks to a WAV file (24-bit) as they are rendered, whole or not at all.

    A ``.wav`` take is written as RF64 with libsndfile's auto-downgrade: it is an ordinary WAV file
    (WAVE_FORMAT_EXTENSIBLE, plus a JUNK chunk) while under 4 GiB and becomes RF64 past it, where a WAV header's
    32-bit sizes would saturate and lose everything after (about 4 h of 48 kHz stereo).

    The blocks go to a hidden ``.NAME.XXXX.part`` file beside ``path``, renamed to ``path`` by :meth:`close`:
    a run killed before closing (SIGKILL, power loss) leaves the part file (a playable WAV up to the last block:
    its header is kept up to date) and neither a cut file nor a damaged earlier take at ``path``. So does a node
    that failed (``keep`` False when it closes; an empty part file is removed), and a take of 0 frames (the node
    stopped before its audio started: its part file is removed, an earlier take keeps its name). On close it also
    writes ``FILE.wav.json`` beside it: the rig time of the first sample (seconds), so what the WAV holds can
    be lined up with the rig's impacts, and its ``segments``: ``{"frame", "rig_time_s"}`` anchors (the first at
    frame 0), a new one where rig time stepped (the clock master restarted) while the take went on, so no frame
    is given a wrong rig time and none is lost.

    Until then that timing is kept beside the part file, in ``.NAME.XXXX.part.json`` (the names:
    :mod:`common.takes`; the .json's keys but ``frames``), written at the first block (when the origin is known)
    and again when rig time steps, and removed once the take has its name and .json: a take killed unnamed keeps
    its place on the rig clock, which ``batteur wav-repair PART`` carries to the take it names. The node holds a
    lock on the part file while it records (:func:`in_use`), so a part file left by a node that is gone can be
    told from a live one.

    ``timeline``: the core's (output sample, rig time) anchors (:meth:`SoundCore.timeline`: the first is sample 0
    at the origin), read on close.
    """

    def __init__(self, path: Path, sample_rate: int, channels: int, timeline: Callable[[], list[tuple[int, float]]],
                 keep: Callable[[], bool] = lambda: True) -> None:
        fmt = wav_format(path, "--wav")
        if fmt.lower() not in TAKE_FORMATS:  # a killed take in it could not be recovered (common.takes)
            raise ValueError(f"--wav {path}: give a file ending in .{', .'.join(TAKE_FORMATS)}, not {path.suffix} "
                             "(the formats `batteur wav-repair` knows a killed take's part file in)")
        path.parent.mkdir(parents=True, exist_ok=True)
        self.path = path
        self.timeline = timeline
        self.keep = keep
        """Asked on close: whether the take gets its name (False: the node failed, the take may be cut short)."""
        self.meta: dict[str, Any] = {}  # what the .json says, taken when the file is closed
        self.anchors_kept = 0  # the timeline's anchors the part file's sidecar holds
        self.lock_fd: int | None = None  # held open (locked) while the part file is being written
        self.finished = False  # closed, named, and its .json written
        # a symlink keeps naming the file it points to; a device or pipe is written in place
        self.in_place = path.exists() and not path.is_file()
        self.target = path if self.in_place else path.resolve()
        self.part = self.target
        if not self.in_place:
            fd, part = tempfile.mkstemp(prefix=part_prefix(self.target.name), suffix=PART_SUFFIX,
                                        dir=self.target.parent)
            self.part = Path(part)
            self.lock_fd = fd
            try:  # a running node's part file: not a leftover (wav-repair and a restarted node check this)
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:  # a file system without locks: recorded all the same
                pass
        rf64 = fmt == "WAV" and not self.in_place  # libsndfile writes no RF64 to a pipe (nor could it upgrade)
        try:
            self.file = sf.SoundFile(self.part, "w", samplerate=sample_rate, channels=channels, subtype="PCM_24",
                                     format="RF64" if rf64 else fmt)
            if rf64 and not sf._snd.sf_command(self.file._file, SFC_RF64_AUTO_DOWNGRADE, sf._ffi.NULL, 1):
                raise RuntimeError("this libsndfile cannot write RF64 that stays WAV under 4 GiB")
            # the header follows every write: a node killed before close leaves a part file that still plays
            sf._snd.sf_command(self.file._file, SFC_SET_UPDATE_HEADER_AUTO, sf._ffi.NULL, 1)
        except BaseException:
            if getattr(self, "file", None) is not None and not self.file.closed:
                self.file.close()
            self._discard()
            raise

    def __call__(self, block: npt.NDArray[np.float32]) -> None:
        anchors = self.timeline()
        if len(anchors) != self.anchors_kept and not self.in_place:  # the first block, or rig time stepped
            self._keep_timing(anchors)  # before the block: no frame on disk without its rig time
        try:
            self.file.write(block)
        except (sf.LibsndfileError, RuntimeError) as exc:  # libsndfile says only "System error."
            raise OSError(f"cannot write more than its first {self.file.frames / self.file.samplerate:.1f} s "
                          f"(libsndfile: {exc} Is the disk full?)") from None

    def _keep_timing(self, anchors: list[tuple[int, float]]) -> None:
        """Write the part file's sidecar (whole or not at all); a failure is said once and the take goes on (its
        .json is written at close all the same)."""
        first = not self.anchors_kept
        self.anchors_kept = len(anchors)
        meta = {"origin_rig_time_s": anchors[0][1], "sample_rate_hz": self.file.samplerate,
                "channels": self.file.channels, "segments": [{"frame": n, "rig_time_s": t} for n, t in anchors],
                "take": self.target.name}
        try:
            write_atomically(part_timing(self.part), json.dumps(meta, indent=2).encode("utf-8"))
        except OSError as exc:
            if first:
                log.warning("cannot write %s (%s): a node killed before it stops would leave its take without its "
                            "rig-time origin", part_timing(self.part), exc.strerror or exc)

    def _unlock(self) -> None:
        if self.lock_fd is not None:
            os.close(self.lock_fd)  # the lock goes with it
            self.lock_fd = None

    def _discard(self) -> None:
        if not self.in_place:
            self.part.unlink(missing_ok=True)
            part_timing(self.part).unlink(missing_ok=True)
        self._unlock()

    def discard(self) -> None:
        """Close and remove what was recorded (a start that failed): ``path`` is left as it was."""
        if not self.file.closed:
            self.file.close()
        self._discard()

    def close(self) -> None:
        """Finish the file (header with the real length) and give it its name. Idempotent, and resumable: a
        close cut short (a second Ctrl-C) finishes when called again."""
        if self.finished:
            return
        if not self.file.closed:
            frames = self.file.frames
            anchors = self.timeline()
            self.meta = {"origin_rig_time_s": anchors[0][1], "sample_rate_hz": self.file.samplerate,
                         "channels": self.file.channels, "frames": frames,
                         "segments": [{"frame": n, "rig_time_s": t} for n, t in anchors if n < frames or n == 0]}
            self.file.close()
            if not self.in_place and not self.keep():
                self._leave_cut_short()
                return
            if not self.in_place and frames == 0:  # nothing played: no empty take over an earlier one's name
                self._leave_empty()
                return
            if self.file.format == "RF64" and self.part.exists() and self.part.stat().st_size > WAV_LIMIT_BYTES:
                log.info("%s is over 4 GiB: written as RF64 (a WAV header cannot hold its length); "
                         "players that read only WAV need it split or converted", self.path)
        if not self.in_place and self.part.exists():
            os.chmod(self.part, _new_file_mode(self.target))
            os.replace(self.part, self.target)
        write_atomically(self.path.with_name(self.path.name + ".json"),
                         json.dumps(self.meta, indent=2).encode("utf-8"))
        if not self.in_place:  # the take's .json has the timing now
            part_timing(self.part).unlink(missing_ok=True)
        self._unlock()
        self.finished = True


    def _leave_empty(self) -> None:
        """:meth:`close` of a take with no frame (the node stopped before its audio started): the part file is removed
        and ``path`` left as it was, an earlier take and its .json included."""
        self.finished = True
        self._discard()
        earlier = " (the earlier take there stays)" if self.target.exists() else ""
        log.info("nothing recorded (0 frames): %s not written%s", self.path, earlier)

    def _leave_cut_short(self) -> None:
        """:meth:`close` of a node that failed: the part file stays (removed if empty), ``path`` is left as it
        was."""
        self.finished = True
        if not self.meta.get("frames"):
            self._discard()
            return
        self._unlock()
        log.warning("the node did not stop cleanly: %s not written (`batteur wav-repair` on the part file names it, "
                    "with its rig-time origin); what was recorded is in %s", self.path, self.part)


def _new_file_mode(path: Path) -> int:
    """Permission bits for the finished file: those of the file it replaces, else a new file's (mkstemp's part
    file is owner-only)."""
    if path.exists():
        return path.stat().st_mode & 0o7777
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


class DeviceSink:
    """Plays rendered blocks on the sound card through a pyo portaudio server.

    The core renders a block per step; pyo's audio callback takes the oldest
    block from a short queue (an empty queue plays silence and counts an
    underrun). Only built when :func:`audio_device_count` is above zero.
    """

    def __init__(self, sample_rate: int, block: int, channels: int, queue_blocks: int = 8) -> None:
        pyo = import_pyo()
        self.block = block
        self.channels = channels
        self.queue: collections.deque[npt.NDArray[np.float32]] = collections.deque(maxlen=queue_blocks)
        self.underruns = 0
        self.lock = threading.Lock()
        with _quiet_stderr():
            self.server = pyo.Server(sr=sample_rate, nchnls=channels, buffersize=block, duplex=0, audio="portaudio")
            self.server.boot()
        self.server.setServer()
        self.tables = [pyo.DataTable(size=block) for _ in range(channels)]
        self.arrays = [np.asarray(t.getBuffer()) for t in self.tables]
        self.readers = [pyo.TableRead(t, freq=t.getRate(), loop=1).play() for t in self.tables]
        for c, reader in enumerate(self.readers):
            reader.out(c)
        self.server.setCallback(self._pull)
        self.server.start()
        self._keep: list[Any] = [pyo]

    def _pull(self) -> None:
        with self.lock:
            block = self.queue.popleft() if self.queue else None
        if block is None:
            self.underruns += 1
            for a in self.arrays:
                a[:] = 0.0
            return
        block2 = block.reshape(self.block, -1)
        for c, a in enumerate(self.arrays):
            a[:] = block2[:, min(c, block2.shape[1] - 1)]

    def __call__(self, block: npt.NDArray[np.float32]) -> None:
        with self.lock:
            self.queue.append(block.copy())

    def close(self) -> None:
        self.server.stop()
        self.server.shutdown()


WAV_HELP = (
    "also record the output to this file, 24-bit (.wav, .rf64, .w64, .aiff, .caf, .au, .flac; a .wav take that "
    "passes 4 GiB, about 4 h, becomes RF64 instead of losing its end); written under a temporary name and given "
    "this one when the node stops "
    "(a node that fails leaves a file already there as it was, and what it recorded under the temporary name). "
    "{start} in the file name is the take's start time, local YYYYmmdd-HHMMSS (take-{start}.wav: "
    "take-20260131-201500.wav, then -2, -3 ... if that name is taken), so each run keeps its own file; the log says "
    "the name. Beside it, its name + .json (take.wav.json) gives origin_rig_time_s (the rig time of the first sample, "
    "seconds: lines the take up with the rig's impacts), sample_rate_hz, channels, frames and segments (frame and "
    "rig time of each stretch: a new one where rig time stepped, the clock master restarted)"
)


class SoundNodeSettings(NodeSettings):
    """Node settings plus the sound service's own: each a flag, a BATTEUR_* variable and a settings file key, as
    every node setting (docs/deployment.md; they were flags only, and a file's ``wav:`` was refused)."""

    kit: str = Field(default="default", min_length=1, description="kit name or kit file (YAML or JSON)")
    wav: Path | None = Field(default=None, description=WAV_HELP)
    device: Literal["auto", "none"] = Field(
        default="auto", description="auto: play on the sound card if portaudio finds one; none: never")
    model: Literal["modal", "sample", "synth"] = Field(
        default="modal", description="initial synthesis model of every instrument: modal, sample or synth")
    block_size: Literal[64, 128, 256, 512] = Field(default=256, description="samples per block: 64, 128, 256 or 512")
    channels: Literal[1, 2] = Field(default=2, description="1 mono, 2 stereo")
    reverb: float = Field(default=0.1, ge=0, le=1, description="room reverb wet/dry, 0..1")
    pedal_impacts: bool = Field(default=False, description="sound impacts on footboards (for rigs without pedal "
                                "physics; see docs/sound.md)")
    sound_params: Path | None = Field(default=None, description="start from this sound parameters file (YAML or "
                                      "JSON: per instrument, what the /batteur/sound/... controls set; "
                                      "docs/sound.md)")
    sound_params_out: Path | None = Field(default=None, description="when the node stops, write what the "
                                          "instruments hold (what differs from the kit's defaults) to this file, "
                                          "for --sound-params (may be the same file): .yaml, .yml or .json, not "
                                          "--wav's take or its .json")

    @field_validator("sound_params", "sound_params_out", mode="before")
    @classmethod
    def _no_params_file(cls, value: Any) -> Any:
        """An empty value is no file, as ``--wav ''``."""
        return None if isinstance(value, str) and not value.strip() else value

    @field_validator("wav", mode="before")
    @classmethod
    def _no_file(cls, value: Any) -> Any:
        """An empty value (``--wav ''``, ``wav: ''`` in a config file) records nothing, as no ``--wav`` (not the
        folder '.'). An empty ``BATTEUR_WAV=`` is no setting at all (common/config.py): a config file's ``wav``
        still applies."""
        return None if isinstance(value, str) and not value.strip() else value

    @field_validator("block_size", "channels", mode="before")
    @classmethod
    def _whole(cls, value: Any) -> Any:
        """A flag's or variable's text ('256') is the number it spells (a Literal of ints takes no text)."""
        if isinstance(value, str) and value.strip().lstrip("+").isdigit():
            return int(value)
        return value


SOUND_OPTIONS = tuple(name for name in SoundNodeSettings.model_fields if name not in NodeSettings.model_fields)
"""The sound node's own settings (``kit``, ``wav``, ``device`` ...)."""


def sound_settings(settings: NodeSettings, extra: argparse.Namespace | None = None) -> SoundNodeSettings:
    """``settings`` as the sound node's: as they are if they are, else with the sound options found in ``extra``
    (a caller that builds the node's settings and options itself); ValueError for a value they refuse."""
    if isinstance(settings, SoundNodeSettings):
        return settings
    own = {k: v for k, v in vars(extra or argparse.Namespace()).items() if k in SOUND_OPTIONS}
    return SoundNodeSettings.model_validate({**settings.model_dump(), **own})


def make_core(settings: NodeSettings, extra: argparse.Namespace | None = None,
              keep_take: Callable[[], bool] = lambda: True,
              keep_params: Callable[[], bool] = lambda: True) -> SoundCore:
    """Build the core and attach the sinks; ValueError (exit 2) for a bad option, InputError (exit 1) for a kit
    file or a --wav path it cannot use. ``keep_take``: asked when the WAV file closes, whether it gets its name;
    ``keep_params``: asked when the core closes, whether ``--sound-params-out`` is written (:func:`save_params`).
    ``settings``: :class:`SoundNodeSettings`, or node settings with the sound options in ``extra``."""
    settings = sound_settings(settings, extra)
    try:
        kit = load_kit(settings.kit)
    except (FileNotFoundError, ValueError) as exc:  # missing, or not a kit
        raise InputError(str(exc)) from None
    if settings.latency_s > MAX_LATENCY_S:  # the other nodes take up to 5 s
        raise ValueError(f"--latency-s {settings.latency_s:g}: the sound service plays at most "
                         f"{MAX_LATENCY_S:g} s late (the range of /batteur/sound/latency)")
    block_s = settings.block_size / 48000
    if settings.latency_s < 3 * block_s:
        log.warning("latency %.1f ms is under three blocks (%.1f ms): most strikes will be late",
                    settings.latency_s * 1e3, 3 * block_s * 1e3)
    sound = SoundSettings(latency=settings.latency_s, origin=None, block_size=settings.block_size,
                          render_ahead=2 * block_s + 0.002,
                          channels=settings.channels, record=False, model=settings.model, reverb=settings.reverb,
                          pedal_impacts=settings.pedal_impacts,
                          horizon=HORIZON_S, max_pending=MAX_PENDING, background_rebuilds=True)
    if settings.wav is not None:  # checked before the (slow) core is built
        if settings.wav.is_dir():
            raise InputError(f"--wav {settings.wav} is a directory: give a file, e.g. {settings.wav / 'take.wav'}")
        wav_format(settings.wav, "--wav")
        wav_name_has_start(settings.wav)
    params = _read_params(settings, kit)  # before the (slow) core is built
    if settings.sound_params_out is not None:
        try:
            check_output_file(settings.sound_params_out, "--sound-params-out")
            check_params_out(settings.sound_params_out, settings.wav)
        except ValueError as exc:
            raise InputError(str(exc)) from None
    core = SoundCore(sound, kit)
    try:
        if settings.sound_params is not None:
            try:
                apply_sound_params(core, params, settings.sound_params)
            except ValueError as exc:  # a value an instrument refuses (every mode above Nyquist)
                raise InputError(str(exc)) from None
            log.info("sound parameters from %s (%d)", settings.sound_params, len(params))
        _attach_sinks(core, settings, keep_take)
    except BaseException:  # a failed start (or Ctrl-C) records nothing and leaves an earlier take alone
        for sink in core.sinks:
            if isinstance(sink, WavSink):
                sink.discard()
        core.sinks = [s for s in core.sinks if not isinstance(s, WavSink)]
        core.close()
        raise
    out = settings.sound_params_out
    if out is not None:  # written as the core closes: before its rebuilds in flight are abandoned, so they are in
        core.before_close = lambda: save_params(core, out) if keep_params() else None
    return core


def _read_params(settings: SoundNodeSettings, kit: Kit) -> list[OscMessage]:
    """The controls ``--sound-params`` holds, checked against the kit; InputError naming the file and the entry."""
    if settings.sound_params is None:
        return []
    try:
        params = load_sound_params(settings.sound_params)
        check_against_kit(params, kit, settings.sound_params)
    except (FileNotFoundError, ValueError) as exc:
        raise InputError(str(exc)) from None
    return params


SAVE_WAIT_S = 2.5
"""At its stop, the node waits up to this long for parameter changes still being computed before it writes
``--sound-params-out`` (a 20,000-mode change takes seconds): within ``batteur rig``'s stop timeout (4 s), which
kills a node that takes longer."""


def save_params(core: SoundCore, path: Path, wait_s: float | None = None) -> None:
    """``--sound-params-out``: what the instruments hold, once changes still computing are in (waited for up to
    ``wait_s`` seconds, :data:`SAVE_WAIT_S` if None, else warned about); logged, never raised (the node is
    stopping). Called as the core closes (:attr:`SoundCore.before_close`): its rebuild worker still runs."""
    wait_s = SAVE_WAIT_S if wait_s is None else wait_s
    if not settle_rebuilds(core, wait_s):
        log.warning("--sound-params-out %s: a parameter change was still being computed after %g s: it is not "
                    "saved", path, wait_s)
    try:
        changed = write_sound_params(core, path)
    except (OSError, ValueError) as exc:
        log.error("--sound-params-out %s: cannot write it (%s)", path, exc)
        return
    log.info("sound parameters written to %s (%d instrument%s changed)", path, len(changed),
             "" if len(changed) == 1 else "s")


def _attach_sinks(core: SoundCore, settings: SoundNodeSettings, keep_take: Callable[[], bool]) -> None:
    """The WAV file and the sound card, as asked; ValueError naming the option that cannot be served."""
    if settings.wav is not None:
        path = expand_wav_path(settings.wav, datetime.now())  # {start}: when recording starts, i.e. now
        blocker = file_in_the_way(path)
        if blocker is not None:  # else mkdir's bare "[Errno 17] File exists"
            raise InputError(f"--wav {path}: {blocker} is a file, not a folder")
        try:
            wav = WavSink(path, core.sample_rate, core.channels, core.timeline, keep_take)
        except (OSError, RuntimeError) as exc:  # soundfile: unwritable path
            raise InputError(f"--wav {path}: cannot write it ({exc})") from None
        core.sinks.append(wav)
        # the name the take ends up with (`batteur rig --record DIR`: DIR/performance.wav), then its part file
        log.info("recording to %s (in %s until the node stops)", path, wav.part.name)
        if not wav.in_place:
            say_leftover_parts(wav.target.parent, wav.part)
    if settings.device == "auto":
        devices = audio_device_count()
        if devices > 0:
            try:
                core.sinks.append(DeviceSink(core.sample_rate, core.block, core.channels))
            except Exception as exc:  # noqa: BLE001 - pyo raises plain Exceptions for a card it cannot open
                raise ValueError(f"--device auto: cannot play on the sound card ({exc}); "
                                 "--device none records without it") from None
            log.info("playing on the sound card (%d portaudio devices)", devices)
        elif settings.wav is not None:
            # `batteur rig --record` gives --wav: telling it to use --wav read as if it were not recording
            log.info("no audio device found: not playing; recording only")
        else:
            # the node whose job is the speakers plays nothing and records nothing: a warning, with what to do (an
            # INFO line was all a teacher's sound laptop said; --device none says it is meant, and silences it)
            log.warning("no audio device found (portaudio lists none): the strikes are not played nor recorded. "
                        "Connect or enable the sound card (not in use by another program? this user in the audio "
                        "group?) and restart with --device auto (the default); or record them with --wav FILE; or "
                        "give --device none if this machine is not to play (silences this warning)")


PD_SOUND_PORT = 9103
"""Where Pd expects the sound service: the control panel's SOUND section (pd/control.pd) and the examples of
pd/batteur-clock-help.pd (compose.yaml's sound port; ``batteur rig`` gives every node its port)."""


def say_port_for_pd(node: Node) -> None:
    """Given no ``--port``, the node listens on any free port: say which, and the command that runs the sound
    service alone where Pd looks for it (on its own clock, without waiting for a physics node). Logged once it
    listens (``setup``)."""
    if node.settings.port != 0 or node.endpoint is None:
        return
    log.info("sound listens on port %d, a free port taken because no --port was given; Pd (pd/control.pd, "
             "pd/batteur-clock) looks for the sound service on %d: to play it alone from Pd, run "
             "`batteur sound --port %d --clock-master self`", node.endpoint.port, PD_SOUND_PORT, PD_SOUND_PORT)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the sound node until SIGINT/SIGTERM; returns the exit code."""
    made: list[SoundCore] = []
    ran: list[Node] = []

    def build(settings: NodeSettings, extra: argparse.Namespace) -> SoundCore:
        # --sound-params-out: written as the core closes (Node.stop), if the node listened (one that never did
        # changed nothing)
        core = make_core(settings, extra, keep_take=lambda: bool(ran) and not ran[0].failed,
                         keep_params=lambda: bool(ran))
        made.append(core)
        return core

    def listening(node: Node) -> None:
        ran.append(node)
        say_port_for_pd(node)

    try:
        # the take is named only if the node ran and did not fail (setup: once it listens); a node that failed,
        # or never listened (its port taken), leaves an earlier take at --wav as it was
        return run_node("sound", build, argv, None,
                        "Run the sound service: impacts in, modal drum sound out (sound card and/or WAV).",
                        settings_cls=SoundNodeSettings, setup=listening)
    finally:
        for core in made:
            core.close()  # closes the WAV file and the sound card (done already if the node ran)


if __name__ == "__main__":
    raise SystemExit(main())
