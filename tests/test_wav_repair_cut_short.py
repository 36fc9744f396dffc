"""``batteur wav-repair`` on a WAV cut short after its header (a copy or a download cut off): the header is given the
whole frames the file holds; and a missing file or a folder is said so in words, not as an errno."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from batteur.tools.wav_repair import repair_wav

ROOT = Path(__file__).resolve().parents[1]


def _repair(*files: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "batteur", "wav-repair", *map(str, files)], cwd=ROOT,
                          capture_output=True, text=True, timeout=60, check=False)


@pytest.mark.parametrize(("channels", "subtype", "frame_bytes"), [(1, "PCM_24", 3), (2, "PCM_16", 4)])
def test_a_wav_cut_at_an_odd_byte_gets_the_frames_it_holds(tmp_path: Path, channels: int, subtype: str,
                                                          frame_bytes: int) -> None:
    audio = np.random.default_rng(5).uniform(-0.9, 0.9, (48000, channels)).astype(np.float32)
    whole = tmp_path / "whole.wav"
    sf.write(whole, audio, 48000, subtype=subtype)
    cut = tmp_path / "half.wav"
    cut.write_bytes(whole.read_bytes()[:100_001])  # `head -c 100001`: mid-frame
    held = (100_001 - 44) // frame_bytes
    run = _repair(cut)
    # was: "left as it is (48000 frames)", rc 0, and readers told of frames the file does not hold
    assert run.returncode == 0, run.stderr
    assert run.stdout == f"{cut}: repaired, {held} frames (the file was cut short: its header said 48000)\n"
    back, rate = sf.read(cut, dtype="float32", always_2d=True)
    reference = sf.read(whole, dtype="float32", always_2d=True)[0]
    assert rate == 48000 and len(back) == held and np.array_equal(back, reference[:held])
    assert sf.info(cut).frames == held
    again = _repair(cut)  # a second run changes nothing
    assert again.stdout == f"{cut}: left as it is ({held} frames)\n"


def test_a_wav_cut_right_after_its_header_is_given_no_frames(tmp_path: Path) -> None:
    whole = tmp_path / "whole.wav"
    sf.write(whole, np.zeros(1000), 48000, subtype="PCM_16")
    cut = tmp_path / "cut.wav"
    cut.write_bytes(whole.read_bytes()[:45])
    result = repair_wav(cut)
    assert result.repaired and result.frames == 0 and result.header_frames == 1000 and result.dropped_bytes == 1
    assert cut.stat().st_size == 44


def test_a_finished_wav_with_a_chunk_after_its_audio_is_left_alone(tmp_path: Path) -> None:
    wav = tmp_path / "tagged.wav"
    sf.write(wav, np.zeros(100), 48000, subtype="PCM_16")
    wav.write_bytes(wav.read_bytes() + b"LIST\x04\x00\x00\x00INFO")  # more than the audio: not cut short
    before = wav.read_bytes()
    assert not repair_wav(wav).repaired and wav.read_bytes() == before


def test_a_missing_file_and_a_folder_are_said_in_words(tmp_path: Path) -> None:
    run = _repair(tmp_path / "missing.wav", tmp_path)
    assert run.returncode == 1
    assert run.stderr.splitlines() == [
        f"batteur wav-repair: error: {tmp_path / 'missing.wav'}: not repaired: no such file",
        f"batteur wav-repair: error: {tmp_path}: not repaired: is a folder, not a WAV file"]  # was [Errno 2/21]
