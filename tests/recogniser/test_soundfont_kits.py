"""Soundfont drum kits for training: each General MIDI drum note rendered by FluidSynth becomes velocity layers
that start at the strike, and a missing font or FluidSynth is a clear error."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from services.recogniser.training import soundfont
from services.recogniser.training.excerpts import load_any_kit
from services.recogniser.training.kits import RENDER_RATE
from services.recogniser.training.one_shots import KIND_NOTE, VELOCITIES
from services.recogniser.training.soundfont import (
    SOUNDFONT_KITS,
    SoundfontKit,
    SoundfontsMissingError,
    render_soundfont_kit,
    require_soundfonts,
)

KIT = "sf-timgm6mb-standard"  # the smallest font (6 MB): CI installs it
needs_font = pytest.mark.skipif(shutil.which("fluidsynth") is None or not SOUNDFONT_KITS[KIT].path.exists(),
                                reason="needs fluidsynth and timgm6mb-soundfont (installed by .ci/run)")


@needs_font
def test_every_drum_note_becomes_velocity_layers_starting_at_the_strike() -> None:
    kit = render_soundfont_kit(KIT)
    assert set(kit.instruments) == set(KIND_NOTE)
    for kind, (instrument,) in kit.instruments.items():
        assert len(instrument.layers) == len(VELOCITIES), kind
        assert instrument.layers[0].lo == 0.0 and instrument.layers[-1].hi == 1.0
        for layer in instrument.layers:
            env = np.abs(layer.audio)
            assert env.max() == pytest.approx(1.0, abs=1e-6)  # loudness comes from the velocity curve
            # the strike is at the start (a one-shot cut late or early would shift every training label)
            assert int(np.argmax(env > 0.1)) < int(0.01 * RENDER_RATE), kind
    # a closed hi-hat dies away long before a crash (they are different samples, cut at the right strikes)
    def tail(kind: str) -> float:
        x = kit.instruments[kind][0].layers[-1].audio
        return float(np.sqrt(np.mean(x[int(0.5 * RENDER_RATE) : int(1.0 * RENDER_RATE)] ** 2)))

    assert tail("hh_closed") < 0.1 * tail("crash")


@needs_font
def test_training_loads_the_soundfont_kit_by_its_name() -> None:
    assert load_any_kit(KIT).name == KIT


def test_a_missing_font_names_the_package_to_install(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    missing = SoundfontKit(tmp_path / "none.sf2", 0, "MIT", "some-soundfont-package")
    monkeypatch.setitem(soundfont.SOUNDFONT_KITS, "sf-missing", missing)
    with pytest.raises(SoundfontsMissingError, match="apt-get install .*some-soundfont-package"):
        require_soundfonts(["sf-missing"])
    with pytest.raises(SoundfontsMissingError):
        render_soundfont_kit("sf-missing")


def test_missing_fluidsynth_is_named(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(soundfont.shutil, "which", lambda _: None)
    with pytest.raises(SoundfontsMissingError, match="fluidsynth"):
        require_soundfonts([])
