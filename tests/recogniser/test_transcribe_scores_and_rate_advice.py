"""What `batteur transcribe` says of a file that is not a recording (a text score, other text, an empty file), and
the rate its low-rate warnings advise: the offline path's (a rate filling its bands to 18 kHz: 32,000 Hz) or the
live path's (it reads 22,050 Hz: 22,050 Hz is enough), docs/recogniser.md."""

from __future__ import annotations

import asyncio
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf
from scipy.signal import resample_poly

from services.recogniser.audio import COMMON_RATES_HZ, band_limited, load_audio, low_rate
from services.recogniser.cli import main
from services.recogniser.errors import AudioFileError
from services.recogniser.features import WIDE, full_rate_hz
from services.recogniser.node import LIVE_BAND_CHECK, LIVE_FULL_RATE_HZ, InputWatch, play_file
from services.recogniser.transcribe import transcribe_file
from tests.ports import free_port

SCORE = "# a groove for Monday's lesson\ntempo 96\nmeter 4/4\nHH |x.x.x.x.|\nSN |..X...X.|\nBD |x...x...|\n"
"""A score in the text format (docs/score-format.md)."""


def _score_said(path: Path, arg: str | None = None) -> str:
    arg = arg or str(path)
    return (f"{path}: this is a score in Batteur's text format, not audio: to hear it, `batteur render {arg} -o DIR`; "
            f"to compare a student's take with it, `batteur compare {arg} TAKE`")


@pytest.mark.parametrize("name", ["groove.txt", "groove.score", "groove", "groove.wav"])
def test_a_text_score_is_said_to_be_a_score_for_render(tmp_path: Path, name: str) -> None:
    path = tmp_path / name  # by its content: a score named .wav is one too
    path.write_text(SCORE)
    with pytest.raises(AudioFileError) as err:
        load_audio(path)
    # was: "not a readable audio file (WAV, FLAC, OGG...): Error opening ...: Format not recognised."
    assert str(err.value) == _score_said(path)


def test_the_commands_said_can_be_pasted(tmp_path: Path) -> None:
    path = tmp_path / "Monday's lesson.txt"
    path.write_text(SCORE)
    with pytest.raises(AudioFileError) as err:
        load_audio(path)
    assert str(err.value) == _score_said(path, f"'{tmp_path}/Monday'\"'\"'s lesson.txt'")


def test_a_text_score_saved_by_notepad_as_unicode_is_one(tmp_path: Path) -> None:
    path = tmp_path / "groove.txt"
    path.write_bytes(SCORE.encode("utf-16"))  # with its byte order mark
    with pytest.raises(AudioFileError) as err:
        load_audio(path)
    assert str(err.value) == _score_said(path)


def test_transcribe_of_a_text_score_fails_in_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path, out = tmp_path / "groove.txt", tmp_path / "x.mid"
    path.write_text(SCORE)
    for live in ([], ["--live", "--to", f"127.0.0.1:{free_port()}"]):
        assert main([str(path), "-o", str(out), *live]) == 1
        err = capsys.readouterr().err
        assert err == f"batteur transcribe: error: {_score_said(path)}\n", err
        assert not out.exists()


@pytest.mark.parametrize("name, text", [
    ("notes.txt", "Practice log\nMonday: 20 minutes of paradiddles\n"),  # text, not a score
    ("typo.txt", "tempo 96\nSN |x.xq|\n"),  # a score that does not read: not called one
    ("take.json", '{"take": 3, "bpm": 96}\n'),
])
def test_other_text_is_said_to_be_text(tmp_path: Path, name: str, text: str) -> None:
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(AudioFileError) as err:
        load_audio(path)
    assert str(err.value) == f"{path}: not a readable audio file (WAV, FLAC, OGG...): it is a text file"


def test_an_empty_file_is_said_to_be_empty(tmp_path: Path) -> None:
    path = tmp_path / "take.wav"
    path.touch()
    with pytest.raises(AudioFileError) as err:
        load_audio(path)
    assert str(err.value) == f"{path}: the file is empty (0 bytes)"  # was "... Format not recognised."


def test_an_image_keeps_its_message(tmp_path: Path) -> None:
    path = tmp_path / "kit.png"
    path.write_bytes(b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR" + bytes(64))
    with pytest.raises(AudioFileError, match=r"not a readable audio file \(WAV, FLAC, OGG\.\.\.\): .*") as err:
        load_audio(path)
    assert "score" not in str(err.value) and "text" not in str(err.value)


def _clicks(path: Path, rate: int, seconds: float = 1.0) -> Path:
    """Clicks four times a second over a faint noise floor, at ``rate`` Hz."""
    audio = 1e-3 * np.random.default_rng(0).standard_normal(int(seconds * rate))
    audio[:: rate // 4] = 0.9
    sf.write(path, audio, rate, subtype="PCM_16")
    return path


def test_the_rates_advised_include_22050_and_24000() -> None:
    assert {22050, 24000} <= set(COMMON_RATES_HZ) and list(COMMON_RATES_HZ) == sorted(COMMON_RATES_HZ)
    assert "record at 24,000 Hz or more" in (low_rate("x.wav", 16000, 23000.0) or "")


def test_the_offline_path_advises_a_rate_filling_its_bands(tmp_path: Path) -> None:
    for rate in (16000, 22050, 24000):
        warnings: list[str] = []
        transcribe_file(_clicks(tmp_path / f"take{rate}.wav", rate), warn=warnings.append)
        assert len(warnings) == 1 and "(record at 32,000 Hz or more if you can)" in warnings[0], warnings
    assert 29000 < full_rate_hz(WIDE) <= 32000


def test_a_file_played_live_is_advised_22050_hz(tmp_path: Path) -> None:
    wav = _clicks(tmp_path / "headset.wav", 16000)
    warnings: list[str] = []
    asyncio.run(play_file(wav, [f"127.0.0.1:{free_port()}"], speed=1e6, warn=warnings.append))
    assert len(warnings) == 1 and warnings[0].startswith(f"{wav}: sampled at 16,000 Hz"), warnings
    # was "(record at 32,000 Hz or more if you can)": the offline path's rate, not the live path's
    assert warnings[0].endswith("(record at 22,050 Hz or more if you can)"), warnings


def test_the_live_command_line_advises_22050_hz(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    wav = _clicks(tmp_path / "headset.wav", 16000)
    assert main([str(wav), "--live", "--speed", "50", "--to", f"127.0.0.1:{free_port()}"]) == 0
    err = capsys.readouterr().err
    assert f"batteur transcribe: warning: {wav}: sampled at 16,000 Hz" in err
    assert "22,050 Hz or more" in err and "32,000" not in err, err


def test_a_live_input_resampled_up_is_advised_22050_hz() -> None:
    heard = np.zeros(22050, np.float32)
    heard[::5512] = 0.9  # clicks, low-passed as an 11,025 Hz source resampled to the live rate would be
    heard = resample_poly(resample_poly(heard, 1, 2), 2, 1).astype(np.float32)
    text = band_limited("input device 'usb'", heard, 22050, LIVE_FULL_RATE_HZ, LIVE_BAND_CHECK)  # as the device's
    assert text is not None and text.endswith("(record at 22,050 Hz or more if you can)"), text
    warnings: list[str] = []
    watch = InputWatch("input device 'usb'", warnings.append, seconds=1.0)
    watch.feed(heard)
    assert warnings == [text]
