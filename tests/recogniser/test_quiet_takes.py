"""A quiet take saved in 16 bits: its quantisation, scaled up with the music to the peak the network reads, was heard
as strikes (docs/recogniser.md, "Your recordings"). A file stored as integers now gets steady noise of about its
quantisation step first (transcribe.NOISE_FILL), as dither would have given it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from services.recogniser.audio import quantum
from services.recogniser.transcribe import DrumEvent, transcribe_file

from .pattern import Pattern


def _take(folder: Path, pattern: Pattern, level_db: float, subtype: str) -> Path:
    """The held-out kit's test pattern at ``level_db`` dBFS of its peak, saved as ``subtype`` (16 bits: no dither)."""
    path = folder / f"take-{-level_db:g}dB-{subtype}.wav"
    sf.write(path, pattern.audio * np.float32(10 ** (level_db / 20)), pattern.sample_rate, subtype=subtype)
    return path


def _notes(events: list[DrumEvent]) -> list[tuple[float, str]]:
    return [(round(e.time, 2), e.name) for e in events]


def test_a_16_bit_take_at_minus_40_dbfs_gains_no_note_over_the_same_take_in_float(tmp_path: Path,
                                                                                   pattern: Pattern) -> None:
    in_float, _ = transcribe_file(_take(tmp_path, pattern, -40.0, "FLOAT"))
    in_16_bits, _ = transcribe_file(_take(tmp_path, pattern, -40.0, "PCM_16"))
    # was 3 notes more (66 for 63; now 64): its quantisation, raised 40 dB with the music, heard as strikes
    assert len(in_16_bits) <= len(in_float) + 1, (_notes(in_float), _notes(in_16_bits))


def test_a_16_bit_take_at_minus_60_dbfs_gains_far_fewer(tmp_path: Path, pattern: Pattern) -> None:
    in_float, _ = transcribe_file(_take(tmp_path, pattern, -60.0, "FLOAT"))
    in_16_bits, _ = transcribe_file(_take(tmp_path, pattern, -60.0, "PCM_16"))
    # was 57 notes more (120 for 63); 16 bits at -60 dBFS keep about 10 bits of the music, so some stay (97 for 63)
    assert len(in_16_bits) - len(in_float) <= 40, (len(in_float), len(in_16_bits))


@pytest.mark.parametrize(("level_db", "subtype"), [(0.0, "PCM_16"), (-20.0, "PCM_16"), (-40.0, "PCM_24")])
def test_a_take_not_quiet_for_its_bits_transcribes_as_in_float(tmp_path: Path, pattern: Pattern, level_db: float,
                                                                subtype: str) -> None:
    """No noise is added to a file whose peak spans 1,024 steps or more (16 bits: -30 dBFS)."""
    in_float, _ = transcribe_file(_take(tmp_path, pattern, level_db, "FLOAT"))
    stored, _ = transcribe_file(_take(tmp_path, pattern, level_db, subtype))
    assert _notes(stored) == _notes(in_float)


def test_no_noise_is_added_to_a_take_loud_for_its_bits() -> None:
    from services.recogniser.model import load_model
    from services.recogniser.transcribe import network_outputs

    net = load_model().offline
    audio = (0.5 * np.sin(np.arange(22050) / 7.0) * (np.arange(22050) % 4410 < 200)).astype(np.float32)
    plain = network_outputs(audio, net, sample_rate=44100)
    assert np.array_equal(network_outputs(audio, net, sample_rate=44100, step=2.0**-15), plain)  # 0.5: 16,384 steps
    quiet = audio * np.float32(1e-3)  # 16 steps: noise added
    assert not np.array_equal(network_outputs(quiet, net, sample_rate=44100, step=2.0**-15),
                              network_outputs(quiet, net, sample_rate=44100))


@pytest.mark.parametrize(("subtype", "fmt", "step"), [
    ("PCM_16", "WAV", 2.0**-15), ("PCM_24", "WAV", 2.0**-23), ("PCM_U8", "WAV", 2.0**-7), ("PCM_16", "FLAC", 2.0**-15),
    ("FLOAT", "WAV", None), ("VORBIS", "OGG", None),
])
def test_the_quantisation_step_is_read_from_the_file(tmp_path: Path, subtype: str, fmt: str,
                                                     step: float | None) -> None:
    path = tmp_path / f"take.{fmt.lower()}"
    sf.write(path, 0.1 * np.sin(np.arange(4410) / 10.0), 44100, subtype=subtype, format=fmt)
    assert quantum(path) == step
    assert quantum(tmp_path / "missing.wav") is None
