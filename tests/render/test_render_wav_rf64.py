"""A render whose performance.wav would pass 4 GiB writes RF64 instead (batteur/render.py, wav_container).

A WAV header's sizes are 32-bit: past 4 GiB (8.3 h of the render's 48 kHz mono, 24-bit) the end of the audio is
lost to readers. The render knows its length before it writes, so it picks RF64 then, and says so; a shorter
render is the same plain WAV as before.
"""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import soundfile as sf

from batteur import render
from services.sound import core as sound_core
from services.sound.core import WAV_DATA_LIMIT_BYTES

RATE_HZ = 48000


def _audio(frames: int, channels: int = 1) -> np.ndarray:
    """Samples a 24-bit file holds exactly (multiples of 2**-23), so they read back bit for bit."""
    rng = np.random.default_rng(2)
    shape = frames if channels == 1 else (frames, channels)
    return (rng.integers(-2**22, 2**22, size=shape) / 2**23).astype(np.float32)


def test_a_wav_past_4_gib_is_planned_as_rf64() -> None:
    most = WAV_DATA_LIMIT_BYTES // 3  # 24-bit mono samples a WAV holds with its header
    assert render.wav_container(most, 1) == "WAV"
    assert render.wav_container(most + 1, 1) == "RF64"
    hours = 3600 * RATE_HZ
    assert render.wav_container(8 * hours, 1) == "WAV"  # the render's 48 kHz mono: 8.3 h fit
    assert render.wav_container(round(8.5 * hours), 1) == "RF64"
    assert render.wav_container(round(4.5 * hours), 2) == "RF64"  # stereo: half as long
    assert render.wav_container(0, 1) == "WAV"


def test_a_stream_planned_past_the_limit_writes_rf64_that_reads_back(tmp_path: Path) -> None:
    path = tmp_path / "performance.wav"
    stream = render.WavStream(path, RATE_HZ, 1, planned_frames=9 * 3600 * RATE_HZ)  # a 9 h render
    audio = _audio(3 * RATE_HZ + 100)
    for block in np.split(audio, range(256, len(audio), 256)):
        stream.write(block)
    stream.close()
    info = sf.info(path)
    assert (info.format, info.subtype, info.samplerate, info.frames) == ("RF64", "PCM_24", RATE_HZ, len(audio))
    assert path.read_bytes()[:4] == b"RF64"
    back, rate = sf.read(path, dtype="float32")
    assert rate == RATE_HZ and np.array_equal(back, audio)


def test_a_stream_under_the_limit_is_the_plain_wav_of_before(tmp_path: Path) -> None:
    audio = _audio(2 * RATE_HZ + 77, channels=2)
    stream = render.WavStream(tmp_path / "streamed.wav", RATE_HZ, 2, planned_frames=len(audio))
    stream.write(audio)
    stream.close()
    sf.write(tmp_path / "whole.wav", audio, RATE_HZ, subtype="PCM_24")  # what the render wrote until now
    assert stream.format == "WAV"
    assert (tmp_path / "streamed.wav").read_bytes() == (tmp_path / "whole.wav").read_bytes()


def _sound() -> SimpleNamespace:
    """What StreamedOutputs.attach takes from a SoundCore."""
    return SimpleNamespace(sample_rate=RATE_HZ, channels=1, block=256, on_block=None)


def test_a_long_render_says_its_wav_is_rf64(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "long").mkdir()
    long = render.StreamedOutputs(tmp_path / "long", 60.0, planned_s=9 * 3600.0, prog="batteur evaluate")
    sound = _sound()
    long.attach(sound)
    sound.on_block(_audio(512))
    long.finish()
    err = capsys.readouterr().err
    assert err == ("batteur evaluate: warning: performance.wav will hold 9.0 h of audio, more than a WAV file can "
                   "describe (4 GiB): written as RF64\n")  # the command rendering, as its other warnings
    assert sf.info(tmp_path / "long" / "performance.wav").format == "RF64"
    (tmp_path / "short").mkdir()
    short = render.StreamedOutputs(tmp_path / "short", 60.0, planned_s=10.75)  # the demo's length
    short.attach(_sound())
    short.finish()
    assert capsys.readouterr().err == ""
    assert (tmp_path / "short" / "performance.wav").read_bytes()[:4] == b"RIFF"


def test_the_whole_piece_writer_picks_rf64_past_the_limit(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    audio = _audio(4800)
    # the limit lowered below this audio's size stands in for 8.3 h of it (4 GiB)
    monkeypatch.setattr(sound_core, "WAV_DATA_LIMIT_BYTES", len(audio) * 3 - 1)
    render.write_outputs(tmp_path / "out", audio, RATE_HZ, [], {"scene": "strike"})
    info = sf.info(tmp_path / "out" / "performance.wav")
    assert info.format == "RF64" and info.frames == len(audio)
    assert np.array_equal(sf.read(tmp_path / "out" / "performance.wav", dtype="float32")[0], audio)
    assert "written as RF64" in capsys.readouterr().err
