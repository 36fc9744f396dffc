"""``--sound-params`` for offline renders: ``python -m services.sound.demo`` and ``batteur render`` (its score and
strike scene renders) start their instruments from the file, and refuse a bad one before rendering."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from batteur.render import apply_render_sound_params, read_render_sound_params
from batteur.strike import run_strikes
from common.kit import EventType, load_kit
from services.sound.demo import main as demo

QUIETER = "instruments: {snare: {level: -20}, kick: {level: -20}, hihat: {level: -20}}\n"


def test_the_demo_plays_the_file(tmp_path: Path) -> None:
    params = tmp_path / "quiet.yaml"
    params.write_text(QUIETER)
    loud, quiet = tmp_path / "loud.wav", tmp_path / "quiet.wav"
    assert demo(["-o", str(loud), "--seconds", "1", "--reverb", "0"]) == 0
    assert demo(["-o", str(quiet), "--seconds", "1", "--reverb", "0", "--sound-params", str(params)]) == 0
    ratio = np.max(np.abs(sf.read(quiet)[0])) / np.max(np.abs(sf.read(loud)[0]))
    assert 0.05 < ratio < 0.2  # -20 dB, give or take the soft limiter


def test_the_demo_refuses_a_bad_file_before_rendering(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    params = tmp_path / "bad.yaml"
    params.write_text("instruments: {snare: {level: 40}}\n")
    out = tmp_path / "out.wav"
    assert demo(["-o", str(out), "--sound-params", str(params)]) == 1
    assert not out.exists()
    assert "instruments.snare.level (/batteur/sound/level): must be at most 12, got 40" in capsys.readouterr().err


def test_a_render_plays_the_file(tmp_path: Path) -> None:
    params = tmp_path / "quiet.yaml"
    params.write_text("instruments: {snare: {level: -20}}\n")
    kit = load_kit("default")
    strikes = [(0.3, 3.0)]
    loud = run_strikes(strikes, EventType.SNARE, kit).audio
    quiet = run_strikes(strikes, EventType.SNARE, kit,
                        prepare=lambda sound: apply_render_sound_params(sound, params)).audio
    assert 0.05 < np.max(np.abs(quiet)) / np.max(np.abs(loud)) < 0.2


def test_a_render_refuses_a_file_its_kit_cannot_take(tmp_path: Path) -> None:
    params = tmp_path / "p.yaml"
    params.write_text("instruments: {bd: {level: -20}}\n")
    with pytest.raises(ValueError, match=r"instruments.bd: the kit 'default' has no instrument 'bd'"):
        read_render_sound_params(params, load_kit("default"))
    with pytest.raises(ValueError, match="no such file"):
        read_render_sound_params(tmp_path / "none.yaml", load_kit("default"))


def test_batteur_render_refuses_a_bad_file_by_name(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from batteur.render import main as render

    params = tmp_path / "p.yaml"
    params.write_text("instruments: {snare: {tension: 5}}\n")
    out = tmp_path / "out"
    assert render(["--strikes", "0.3:3", "-o", str(out), "--quiet", "--sound-params", str(params)]) == 1
    assert "instruments.snare.tension (/batteur/sound/tension): must be at least 10, got 5" in capsys.readouterr().err
    assert not (out / "performance.wav").exists()
