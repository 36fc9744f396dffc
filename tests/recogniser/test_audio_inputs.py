"""Audio files a user brings that are not what they seem: a FIFO, a WAV whose header says less than it holds
(0 bytes: a take cut short), stereo channels that cancel when mixed."""

from __future__ import annotations

import os
import shutil
import struct
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from services.recogniser.audio import load_audio
from services.recogniser.errors import AudioFileError

ROOT = Path(__file__).resolve().parents[2]
RATE = 8000


def _clicks(seconds: float = 2.0) -> np.ndarray:
    """Clicks four times a second over a faint noise floor."""
    audio = 1e-3 * np.random.default_rng(0).standard_normal(int(seconds * RATE)).astype(np.float32)
    audio[:: RATE // 4] = 0.9
    return audio


def _with_data_size(path: Path, size: int) -> None:
    """Rewrite the size of the WAV file's ``data`` chunk (what a recorder writes before it knows the length)."""
    data = bytearray(path.read_bytes())
    at = data.index(b"data") + 4
    data[at : at + 4] = struct.pack("<I", size)
    path.write_bytes(bytes(data))


def test_a_fifo_is_refused_without_waiting_for_a_writer(tmp_path: Path) -> None:
    fifo = tmp_path / "take.wav"
    os.mkfifo(fifo)

    def writer() -> None:  # so that a reader opening the FIFO is not stuck for ever: it reads an empty file
        os.close(os.open(fifo, os.O_WRONLY))

    thread = threading.Thread(target=writer, daemon=True)
    thread.start()
    try:
        with pytest.raises(AudioFileError, match="not a regular file") as err:  # was "not a readable audio file"
            load_audio(fifo)  # (and without a writer it waited for one for ever)
        assert str(fifo) in str(err.value)
    finally:
        reader = os.open(fifo, os.O_RDONLY | os.O_NONBLOCK)  # lets the writer go if nothing opened the FIFO
        thread.join()
        os.close(reader)


def test_the_cli_refuses_a_fifo_with_one_line(tmp_path: Path) -> None:
    fifo = tmp_path / "take.wav"
    os.mkfifo(fifo)
    # the timeout only keeps a hanging run (the CLI opened the FIFO to see how long it is) from stopping the suite
    done = subprocess.run([sys.executable, "-m", "services.recogniser.cli", str(fifo), "-o", str(tmp_path / "x.mid")],
                          cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert done.returncode == 1
    assert done.stderr.strip().splitlines() == [
        f"batteur transcribe: error: {fifo}: not a regular file but a pipe (FIFO); give an audio file saved to disk "
        "(WAV, FLAC, OGG...)"]  # as every loader says it (common/input_file.py)
    assert not (tmp_path / "x.mid").exists()


def test_a_wav_whose_header_says_no_audio_points_to_wav_repair(tmp_path: Path) -> None:
    take = tmp_path / "take.wav"
    sf.write(take, _clicks(), RATE, subtype="PCM_16")
    _with_data_size(take, 0)  # Pd's writesf~ until the take is closed
    with pytest.raises(AudioFileError, match=r"header says it holds no audio .*`batteur wav-repair ") as err:
        load_audio(take)  # was "the file holds no audio (0 samples)": it holds 2 s
    assert str(take) in str(err.value)
    empty = tmp_path / "empty.wav"
    sf.write(empty, np.zeros(0, np.float32), RATE)
    with pytest.raises(AudioFileError, match=r"the file holds no audio \(0 samples\)$"):  # truly empty: no hint
        load_audio(empty)


def test_a_wav_whose_header_says_less_than_it_holds_is_transcribed_with_a_warning(tmp_path: Path) -> None:
    take = tmp_path / "take.wav"
    sf.write(take, _clicks(), RATE, subtype="PCM_16")
    _with_data_size(take, RATE // 2 * 2)  # half a second of the two: a header last updated then
    warnings: list[str] = []
    audio = load_audio(take, sample_rate=RATE, warn=warnings.append)
    assert len(audio) == RATE // 2
    assert len(warnings) == 1 and str(take) in warnings[0]  # was no word: 1.5 s left out silently
    assert "is not a WAV chunk" in warnings[0] and "transcribing the 0.5 s it holds" in warnings[0]


def test_a_wav_with_a_chunk_after_its_audio_gives_no_warning(tmp_path: Path) -> None:
    take = tmp_path / "take.wav"
    sf.write(take, _clicks(), RATE, subtype="PCM_16")
    info = b"INFOISFT" + struct.pack("<I", 4) + b"abc\0"
    take.write_bytes(take.read_bytes() + b"LIST" + struct.pack("<I", len(info)) + info)
    warnings: list[str] = []
    assert len(load_audio(take, sample_rate=RATE, warn=warnings.append)) == 2 * RATE
    assert warnings == []


def test_stereo_channels_that_cancel_are_named(tmp_path: Path) -> None:
    path = tmp_path / "inverted.wav"
    clicks = _clicks()
    sf.write(path, np.stack([clicks, -clicks], axis=1), RATE, subtype="FLOAT")
    with pytest.raises(AudioFileError, match="once its channels are mixed: they cancel"):  # was just "silent"
        load_audio(path)
    sf.write(path, np.zeros((RATE, 2), np.float32), RATE)
    with pytest.raises(AudioFileError, match=r"the audio is silent \(peak"):  # silent channels are just silent
        load_audio(path)


def test_a_file_without_read_permission_says_so(tmp_path: Path) -> None:
    path = tmp_path / "take.wav"
    sf.write(path, _clicks(), RATE, subtype="PCM_16")
    path.chmod(0)
    code = f"from services.recogniser.audio import load_audio\nload_audio({str(path)!r})"
    command = [sys.executable, "-c", code]
    if os.geteuid() == 0:  # root reads any file: run without the capabilities that let it
        if shutil.which("setpriv") is None:
            pytest.skip("running as root without setpriv")
        command = ["setpriv", "--bounding-set=-dac_override,-dac_read_search", *command]
    done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=120)
    # was "not a readable audio file (WAV, FLAC, OGG...): Error opening ...: System error."
    assert f"AudioFileError: {path}: cannot read the file (Permission denied)" in done.stderr


@pytest.mark.parametrize(("suffix", "fmt", "words"), [
    ("flac", "FLAC", "cannot decode the audio after"),  # was refused: "cannot decode the audio: ... lost sync"
    ("ogg", "OGG", "its Ogg stream stops without its end mark"),  # was no word
    ("aiff", "AIFF", "shorter than its header says"),  # was no word
])
def test_a_compressed_or_aiff_recording_cut_off_is_transcribed_with_a_warning(
        tmp_path: Path, suffix: str, fmt: str, words: str) -> None:
    path = tmp_path / f"take.{suffix}"
    rng = np.random.default_rng(1)  # noise: every FLAC frame holds bytes, so half the file is about half the audio
    sf.write(path, (0.3 * rng.standard_normal(4 * RATE)).astype(np.float32), RATE, format=fmt)
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    warnings: list[str] = []
    audio = load_audio(path, sample_rate=RATE, warn=warnings.append)
    assert RATE <= len(audio) < 4 * RATE
    assert len(warnings) == 1 and str(path) in warnings[0] and words in warnings[0]
