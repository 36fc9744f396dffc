"""The first end-to-end strike, offline: physics contact -> interaction impact -> sound onset."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from batteur import render
from batteur.strike import run_strikes

STRIKES = [(0.2, 3.0), (0.6, 1.5), (1.0, 4.5)]
LATENCY = 0.05
BLOCK = 256


def onset_times(audio: np.ndarray, sample_rate: int, threshold: float = 0.02) -> list[float]:
    """Times (s) where the signal first exceeds ``threshold`` after at least 50 ms below it."""
    loud = np.flatnonzero(np.abs(audio) > threshold)
    onsets: list[float] = []
    last = -1e9
    for index in loud:
        if index - last > 0.05 * sample_rate:
            onsets.append(index / sample_rate)
        last = index
    return onsets


@pytest.fixture(scope="module")
def result():  # type: ignore[no-untyped-def]
    return run_strikes(STRIKES, latency_s=LATENCY, tail_s=0.3)


def test_one_impact_per_strike_at_the_contact_time(result) -> None:  # type: ignore[no-untyped-def]
    assert len(result.impacts) == len(STRIKES)
    assert result.contacts >= len(STRIKES)
    for impact, (t, speed) in zip(result.impacts, STRIKES, strict=True):
        assert impact.instrument == "snare"
        assert abs(impact.time - t) <= 0.002  # two physics steps
        assert impact.velocity == pytest.approx(speed, rel=0.1)


def test_each_strike_is_heard_within_one_block_of_its_time_plus_latency(result) -> None:  # type: ignore[no-untyped-def]
    onsets = onset_times(result.audio, result.sample_rate)
    assert len(onsets) == len(STRIKES)
    for onset, impact in zip(onsets, result.impacts, strict=True):
        assert abs(onset - (impact.time + LATENCY)) <= BLOCK / result.sample_rate


def test_harder_strikes_are_louder(result) -> None:  # type: ignore[no-untyped-def]
    sr = result.sample_rate
    peaks = [float(np.abs(result.audio[int((t + LATENCY) * sr): int((t + LATENCY + 0.1) * sr)]).max())
             for t, _ in STRIKES]
    assert peaks[1] < peaks[0] < peaks[2]


def test_render_command_writes_wav_impacts_and_report(tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert render.main(["-o", str(out), "--strikes", "0.2:3,0.5:2", "--quiet"]) == 0
    audio, sr = sf.read(out / "performance.wav")
    assert sr == 48000 and len(audio) > 0.5 * sr
    with (out / "impacts.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert [float(r["time"]) for r in rows] == pytest.approx([0.2, 0.5], abs=0.002)
    report = json.loads((out / "report.json").read_text())
    assert report["impacts"] == 2


def test_bad_schedule_fails_clearly_and_writes_nothing(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    assert render.main(["-o", str(out), "--strikes", "0.2:fast", "--quiet"]) == 2
    assert "TIME:SPEED" in capsys.readouterr().err
    assert not out.exists()
