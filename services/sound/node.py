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
import json
import logging
import threading
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import soundfile as sf

from common.config import NodeSettings
from common.kit import load_kit
from common.runtime import run_node
from services.sound.core import SoundCore, SoundSettings
from services.sound.pyo_stage import _quiet_stderr, audio_device_count, import_pyo

log = logging.getLogger("batteur.sound")


class WavSink:
    """Appends blocks to a WAV file (24-bit) as they are rendered.

    On close it writes ``FILE.wav.json`` beside it: the rig time of the first
    sample (seconds), so what the WAV holds can be lined up with the rig's
    impacts.
    """

    def __init__(self, path: Path, sample_rate: int, channels: int, origin: Callable[[], float]) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        self.path = path
        self.origin = origin
        self.file = sf.SoundFile(path, "w", samplerate=sample_rate, channels=channels, subtype="PCM_24")

    def __call__(self, block: npt.NDArray[np.float32]) -> None:
        self.file.write(block)

    def close(self) -> None:
        if self.file.closed:
            return
        meta = {"origin_rig_time_s": self.origin(), "sample_rate_hz": self.file.samplerate,
                "channels": self.file.channels, "frames": self.file.frames}
        self.file.close()
        self.path.with_name(self.path.name + ".json").write_text(json.dumps(meta, indent=2), encoding="utf-8")


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


def add_arguments(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("sound")
    group.add_argument("--kit", default="default", help="kit name or kit file (default: default)")
    group.add_argument("--wav", type=Path, default=None, help="also write the output to this WAV file")
    group.add_argument("--device", choices=("auto", "none"), default="auto",
                       help="auto: play on the sound card if portaudio finds one; none: never")
    group.add_argument("--model", choices=("modal", "sample", "synth"), default="modal",
                       help="initial synthesis model of every instrument (default: modal)")
    group.add_argument("--block-size", type=int, choices=(64, 128, 256, 512), default=256, help="samples per block")
    group.add_argument("--channels", type=int, choices=(1, 2), default=2, help="1 mono, 2 stereo (default 2)")
    group.add_argument("--reverb", type=float, default=0.1, help="room reverb wet/dry 0..1 (default 0.1)")
    group.add_argument("--pedal-impacts", action="store_true",
                       help="sound impacts on footboards (for rigs without pedal physics; see docs/sound.md)")


def make_core(settings: NodeSettings, extra: argparse.Namespace) -> SoundCore:
    """Build the core and attach the sinks; ValueError for a bad option."""
    try:
        kit = load_kit(extra.kit)
    except FileNotFoundError as exc:
        raise ValueError(str(exc)) from None
    if not 0.0 <= extra.reverb <= 1.0:
        raise ValueError(f"--reverb {extra.reverb} is outside 0..1")
    block_s = extra.block_size / 48000
    if settings.latency_s < 3 * block_s:
        log.warning("latency %.1f ms is under three blocks (%.1f ms): most strikes will be late",
                    settings.latency_s * 1e3, 3 * block_s * 1e3)
    sound = SoundSettings(latency=settings.latency_s, origin=None, block_size=extra.block_size,
                          render_ahead=2 * block_s + 0.002,
                          channels=extra.channels, record=False, model=extra.model, reverb=extra.reverb,
                          pedal_impacts=bool(getattr(extra, "pedal_impacts", False)))
    core = SoundCore(sound, kit)
    if extra.wav is not None:
        if extra.wav.is_dir():
            raise ValueError(f"--wav {extra.wav} is a directory: give a file, e.g. {extra.wav / 'take.wav'}")
        try:
            core.sinks.append(WavSink(extra.wav, core.sample_rate, core.channels, lambda: core.scheduler.origin))
        except (OSError, TypeError, RuntimeError) as exc:  # soundfile: unknown extension, unwritable path
            raise ValueError(f"--wav {extra.wav}: cannot write it ({exc})") from None
        log.info("writing %s", extra.wav)
    if extra.device == "auto":
        devices = audio_device_count()
        if devices > 0:
            core.sinks.append(DeviceSink(core.sample_rate, core.block, core.channels))
            log.info("playing on the sound card (%d portaudio devices)", devices)
        else:
            log.info("no audio device found: not playing (use --wav to record)")
    return core


def main(argv: Sequence[str] | None = None) -> int:
    """Run the sound node until SIGINT/SIGTERM; returns the exit code."""
    made: list[SoundCore] = []

    def build(settings: NodeSettings, extra: argparse.Namespace) -> SoundCore:
        core = make_core(settings, extra)
        made.append(core)
        return core

    try:
        return run_node("sound", build, argv, add_arguments,
                        "Run the sound service: impacts in, modal drum sound out (sound card and/or WAV).")
    finally:
        for core in made:
            core.close()  # closes the WAV file and the sound card


if __name__ == "__main__":
    raise SystemExit(main())
