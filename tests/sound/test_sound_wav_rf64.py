"""A .wav take that passes 4 GiB (about 4 h of 48 kHz stereo) is written as RF64 instead of losing its end."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from services.sound import core as sound_core
from services.sound.core import WAV_LIMIT_BYTES, SoundCore, SoundSettings
from services.sound.node import WavSink

BLOCK = np.full((256, 2), 0.25, dtype=np.float32)


def test_a_wav_take_past_4_gib_keeps_all_it_holds(tmp_path: Path) -> None:
    wav = tmp_path / "take.wav"
    sink = WavSink(wav, 48000, 2, lambda: [(0, 0.0)])
    sink(BLOCK)
    os.truncate(sink.part, WAV_LIMIT_BYTES + 2**20)  # as if 4 h had been recorded (sparse: nothing written)
    sink(BLOCK)
    sink.close()
    info = sf.info(wav)
    # was: a WAV header saying 512 frames; whatever came after 4 GiB lost to any reader
    assert info.format == "RF64"
    assert info.frames * 3 * 2 > WAV_LIMIT_BYTES
    assert wav.stat().st_size - info.frames * 3 * 2 < 1024  # the header covers the whole file


def test_a_short_wav_take_is_an_ordinary_wav(tmp_path: Path) -> None:
    wav = tmp_path / "take.wav"
    sink = WavSink(wav, 48000, 2, lambda: [(0, 0.0)])
    for _ in range(10):
        sink(BLOCK)
    sink.close()
    assert wav.read_bytes()[:4] == b"RIFF"
    audio, rate = sf.read(wav, dtype="float32")
    assert rate == 48000 and audio.shape == (2560, 2) and np.allclose(audio, 0.25, atol=1e-6)


def test_an_offline_render_past_the_wav_limit_is_written_as_rf64(tmp_path: Path,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    core = SoundCore(SoundSettings(record=True))
    core.render(0.5)
    frames = len(core.recording())
    assert sf.info(core.write_wav(tmp_path / "short.wav")).format == "WAV"  # under the limit: a plain WAV
    # the limit lowered below this render's size stands in for a 4 h render (about 4 GiB of samples)
    monkeypatch.setattr(sound_core, "WAV_DATA_LIMIT_BYTES", frames)
    info = sf.info(core.write_wav(tmp_path / "long.wav"))
    assert info.format == "RF64" and info.frames == frames  # was: a WAV whose header cannot hold the length
