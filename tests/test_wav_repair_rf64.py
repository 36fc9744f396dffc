"""``batteur wav-repair`` on RF64 files: ``batteur render`` writes RF64 past 4 GiB, and a render cut off while
writing (a crash, a full disk) left a file wav-repair refused (``not a RIFF/WAVE file``). Small RF64 files stand in
for the long ones (libsndfile writes RF64 at any length when asked to)."""

from __future__ import annotations

import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from batteur.tools.wav_repair import repair_wav

ROOT = Path(__file__).resolve().parents[1]
RATE_HZ = 48000
RF64_NOTE = "RF64: its ds64 sizes set to the audio on disk"
"""What the command says it did to an RF64 file."""


def _repair(*files: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "batteur", "wav-repair", *map(str, files)], cwd=ROOT,
                          capture_output=True, text=True, timeout=60, check=False)


def _audio(frames: int, channels: int) -> np.ndarray:
    return np.random.default_rng(11).uniform(-0.9, 0.9, (frames, channels)).astype(np.float32)


def _ds64(path: Path) -> tuple[int, int, int]:
    """The RIFF size, data size and sample count an RF64 file's ds64 chunk holds (the first chunk)."""
    raw = path.read_bytes()
    assert raw[:4] == b"RF64" and raw[12:16] == b"ds64"
    return struct.unpack("<QQQ", raw[20:44])


def _unfinalised(path: Path, audio: np.ndarray, subtype: str) -> None:
    """An RF64 file as libsndfile leaves it on disk until it is closed (a render killed while writing): the
    audio written, the ds64 sizes 0 (its RIFF size -8), the 32-bit sizes 0xFFFFFFFF."""
    with sf.SoundFile(path, "w", RATE_HZ, audio.shape[1], subtype, format="RF64") as f:
        f.write(audio)
        f.flush()
        on_disk = path.read_bytes()
    path.write_bytes(on_disk + b"\x07")  # and a frame it had begun to write


@pytest.mark.parametrize(("channels", "subtype", "frame_bytes"), [(1, "PCM_24", 3), (2, "PCM_16", 4)])
def test_an_rf64_file_cut_mid_frame_gets_the_frames_it_holds(tmp_path: Path, channels: int, subtype: str,
                                                             frame_bytes: int) -> None:
    audio = _audio(48000, channels)
    whole = tmp_path / "whole.wav"
    sf.write(whole, audio, RATE_HZ, subtype=subtype, format="RF64")
    header_bytes = len(whole.read_bytes()) - 48000 * frame_bytes
    cut = tmp_path / "cut.wav"
    cut.write_bytes(whole.read_bytes()[:100_001])  # `head -c 100001`: mid-frame
    held = (100_001 - header_bytes) // frame_bytes
    run = _repair(cut)
    # was: "not repaired: not a RIFF/WAVE file", rc 1
    assert run.returncode == 0, run.stderr
    assert run.stdout == f"{cut}: repaired, {held} frames ({RF64_NOTE}; the file was cut short: its header said " \
                         f"48000)\n"
    info = sf.info(cut)
    assert info.format == "RF64" and info.frames == held
    back = sf.read(cut, dtype="float32", always_2d=True)[0]
    assert np.array_equal(back, sf.read(whole, dtype="float32", always_2d=True)[0][:held])
    riff_size, data_size, samples = _ds64(cut)
    assert (riff_size, data_size, samples) == (cut.stat().st_size - 8, held * frame_bytes, held)
    assert _repair(cut).stdout == f"{cut}: left as it is ({held} frames)\n"  # a second run changes nothing


@pytest.mark.parametrize(("channels", "subtype"), [(1, "PCM_24"), (2, "FLOAT")])
def test_an_unfinalised_rf64_file_gets_back_every_whole_frame(tmp_path: Path, channels: int, subtype: str) -> None:
    audio = _audio(4801, channels)  # an odd count: 24-bit mono needs RIFF's pad byte
    take = tmp_path / "performance.wav"
    _unfinalised(take, audio, subtype)
    assert sf.info(take).frames == 0  # what a player sees before the repair
    run = _repair(take)
    assert run.returncode == 0, run.stderr
    assert run.stdout == f"{take}: repaired, 4801 frames ({RF64_NOTE})\n"
    reference = tmp_path / "reference.wav"
    sf.write(reference, audio, RATE_HZ, subtype=subtype, format="RF64")
    back = sf.read(take, dtype="float32", always_2d=True)[0]
    assert sf.info(take).format == "RF64"
    assert np.array_equal(back, sf.read(reference, dtype="float32", always_2d=True)[0])
    assert take.read_bytes() == reference.read_bytes()  # the header libsndfile writes on closing, to the byte


def test_a_finished_rf64_file_is_left_as_it_is(tmp_path: Path) -> None:
    done = tmp_path / "done.wav"
    sf.write(done, _audio(1001, 2), RATE_HZ, subtype="PCM_24", format="RF64")
    before = done.read_bytes()
    result = repair_wav(done)
    assert not result.repaired and result.frames == 1001 and done.read_bytes() == before


def test_a_file_neither_wav_nor_rf64_is_still_refused_in_words(tmp_path: Path) -> None:
    w64 = tmp_path / "take.w64"
    sf.write(w64, _audio(100, 1), RATE_HZ, subtype="PCM_16", format="W64")
    notes = tmp_path / "notes.wav"
    notes.write_bytes(b"RF64\xff\xff\xff\xffNOTE not audio")  # RF64's magic, but no WAVE inside
    before = w64.read_bytes(), notes.read_bytes()
    run = _repair(w64, notes)
    assert run.returncode == 1 and run.stdout == ""
    assert run.stderr.splitlines() == [f"batteur wav-repair: error: {w64}: not repaired: not a RIFF/WAVE file",
                                       f"batteur wav-repair: error: {notes}: not repaired: not a RIFF/WAVE file"]
    assert (w64.read_bytes(), notes.read_bytes()) == before
