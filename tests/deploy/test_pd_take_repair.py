"""A Pd take still recording when Pd exits says 0 frames; batteur.tools.wav_repair gives it back its audio.

Pd 0.53 (Debian bookworm) has no [closebang] and [writesf~] has no way to update its header before ``stop``,
and Pd's SIGINT handler exits without closing files: the repair is done afterwards, from the file's size.
"""

from __future__ import annotations

import signal
import socket
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from batteur.tools.wav_repair import repair_wav
from common.messages import Impact, encode, encode_raw
from tests.deploy.pdrun import PD_DIR, PdProcess
from tests.ports import free_port

pytestmark = pytest.mark.timeout(120)
ROOT = Path(__file__).resolve().parents[2]


def _repair(*files: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "batteur.tools.wav_repair", *map(str, files)], cwd=ROOT,
                          capture_output=True, text=True, timeout=60, check=False)


def _strike(seq: int, t: float) -> bytes:
    return encode(Impact(seq=seq, time=t, instrument="snare", zone="centre", r=0.2, theta=0.0, velocity=4.0,
                         impulse=0.01, peak_force=100.0, duration=0.003, part="right_stick_tip"))


def test_a_take_cut_short_by_pd_exiting_is_repaired_with_its_strikes(tmp_path: Path) -> None:
    port = free_port()
    pd = PdProcess(PD_DIR / "sound-client.pd", sends=[f"sc-dir symbol {tmp_path}", f"sc-port {port}"])
    take = tmp_path / "take-4.wav"
    try:
        pd.wait_for(lambda lines: any(f"listen {port}" in line for line in lines))
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.sendto(encode_raw("/pd/record", [4]), ("127.0.0.1", port))
            pd.wait_for(lambda lines: bool(pd.printed("batteur-record")))
            for k in range(3):
                s.sendto(_strike(k, 10.0 + k), ("127.0.0.1", port))
                pd.wait_for(lambda lines, n=k + 1: len(pd.printed("batteur-impact")) == n)
            # writesf~ writes from a thread, in chunks: wait until a second is on disk (the strikes are in it)
            pd.wait_for(lambda lines: take.stat().st_size > 44 + 2 * 48000, timeout=30)
        pd.popen.send_signal(signal.SIGINT)  # docker compose stop, with no /pd/stop first
        pd.popen.wait(timeout=10)
    finally:
        pd.stop()
    size = take.stat().st_size
    assert sf.info(take).frames == 0  # Pd's limitation: the header of a take it never closed
    result = _repair(take)
    assert result.returncode == 0 and result.stdout.startswith(f"{take}: repaired, "), result.stderr
    audio, rate = sf.read(take)
    info = sf.info(take)
    assert info.channels == 1 and info.subtype == "PCM_16" and len(audio) == (size - 44) // 2
    assert len(audio) > rate  # every whole frame on disk is kept
    loud = np.flatnonzero(np.abs(audio) > 0.05)
    assert loud.size > 0, "the strikes are in the repaired take"
    # a second run changes nothing
    before = take.read_bytes()
    again = _repair(take)
    assert again.returncode == 0 and "left as it is" in again.stdout and take.read_bytes() == before


def _cut_short(path: Path, audio: np.ndarray, rate: int, subtype: str, extra: bytes = b"") -> None:
    """``path`` as [writesf~] leaves a take it never closed: RIFF and data sizes of an empty file."""
    sf.write(path, audio, rate, subtype=subtype, format="WAV")
    raw = bytearray(path.read_bytes())
    data = raw.index(b"data")
    raw[data + 4:data + 8] = struct.pack("<I", 0)
    raw[4:8] = struct.pack("<I", data + 8 - 8)
    path.write_bytes(bytes(raw) + extra)


@pytest.mark.parametrize(("channels", "subtype"), [(1, "PCM_16"), (2, "PCM_24"), (1, "FLOAT")])
def test_every_whole_frame_comes_back_exactly(tmp_path: Path, channels: int, subtype: str) -> None:
    rng = np.random.default_rng(3)
    audio = rng.uniform(-0.9, 0.9, (4801, channels)).astype(np.float32)  # an odd count: 24-bit mono pads
    take = tmp_path / "take.wav"
    _cut_short(take, audio, 48000, subtype, extra=b"\x01")  # and a partial frame Pd had begun to write
    assert sf.info(take).frames == 0
    result = repair_wav(take)
    assert result.repaired and result.frames == 4801 and result.dropped_bytes == 1
    back, rate = sf.read(take, dtype="float32", always_2d=True)
    reference = tmp_path / "reference.wav"
    sf.write(reference, audio, 48000, subtype=subtype, format="WAV")
    assert rate == 48000 and np.array_equal(back, sf.read(reference, dtype="float32", always_2d=True)[0])


def test_a_finished_take_and_other_files_are_left_alone(tmp_path: Path) -> None:
    whole = tmp_path / "whole.wav"
    sf.write(whole, np.zeros(100), 44100, subtype="PCM_16")
    before = whole.read_bytes()
    notes = tmp_path / "notes.wav"
    notes.write_text("not audio")
    result = _repair(whole, notes, tmp_path / "missing.wav")
    assert whole.read_bytes() == before and notes.read_text() == "not audio"
    assert result.stdout == f"{whole}: left as it is (100 frames)\n"
    assert result.returncode == 1
    assert result.stderr.splitlines() == [
        f"batteur wav-repair: error: {notes}: not repaired: not a RIFF/WAVE file",
        f"batteur wav-repair: error: {tmp_path / 'missing.wav'}: not repaired: no such file"]
