"""The sound node on loopback: impacts over UDP become audio in a WAV file; bad controls are counted."""

from __future__ import annotations

import argparse
import asyncio
import socket
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf
from sound_helpers import impact

from common.config import load_settings
from common.messages import DropReason, OscMessage, encode_raw
from common.messages.sound import SoundRejected, SoundTension
from common.runtime import Node
from common.transport import UdpEndpoint
from services.sound.node import make_core


async def wait_for(cond: Callable[[], bool], timeout: float = 10.0) -> None:
    end = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > end:
            raise AssertionError("timed out")
        await asyncio.sleep(0.01)


def test_node_plays_impacts_into_a_wav_and_counts_bad_controls(tmp_path: Path) -> None:
    wav = tmp_path / "take.wav"

    async def main() -> None:
        tester = await UdpEndpoint.open()
        got: list[OscMessage] = []
        tester.set_handler(lambda m, s: got.append(m))
        settings = load_settings({"role": "sound", "discovery": False, "clock_master": "self", "latency_s": 0.05,
                                  "peers": [f"tester={tester.local_address}"]})
        extra = argparse.Namespace(kit="default", wav=wav, device="none", model="modal", block_size=256,
                                   channels=2, reverb=0.0)
        core = make_core(settings, extra)
        node = Node(core, settings)
        task = asyncio.ensure_future(node.run())
        await wait_for(lambda: node.endpoint is not None and core.next_sample > 4800)
        assert node.endpoint is not None
        target = node.endpoint.local_address
        tester.send(impact(1, node.clock.now(), "snare", velocity=5.0), target)
        tester.send(SoundTension(instrument="ride", value=2000.0), target)  # a cymbal has no tension
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as raw:
            raw.sendto(encode_raw("/batteur/sound/tension", ["snare", 1e9]), ("127.0.0.1", node.endpoint.port))
        await wait_for(lambda: any(isinstance(m, SoundRejected) for m in got))
        await wait_for(lambda: node.endpoint is not None and node.endpoint.stats.dropped[DropReason.OUT_OF_RANGE] == 1)
        await wait_for(lambda: core.stats.strikes == 1)
        await asyncio.sleep(0.3)
        node.request_stop()
        await asyncio.wait_for(task, 5.0)
        tester.close()
        rejected = next(m for m in got if isinstance(m, SoundRejected))
        assert isinstance(rejected, SoundRejected) and "tension" in rejected.reason
        assert core.late == 0

    asyncio.run(main())
    audio, rate = sf.read(wav)
    assert rate == 48000 and audio.shape[1] == 2
    assert np.max(np.abs(audio)) > 0.05  # the snare is in the file


def test_a_wav_path_that_cannot_be_written_is_a_clear_error(tmp_path: Path) -> None:
    settings = load_settings({"role": "sound", "discovery": False, "clock_master": "self"})
    a_file = tmp_path / "notes.txt"
    a_file.write_text("mine")
    for wav, says in ((tmp_path, "is a directory"), (tmp_path / "take.txt", "give a file ending in .wav"),
                      (a_file / "take.wav", "notes.txt is a file, not a folder")):
        extra = argparse.Namespace(kit="default", wav=wav, device="none", model="modal", block_size=256,
                                   channels=2, reverb=0.0)
        with pytest.raises(ValueError, match=says):
            make_core(settings, extra)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt"]
