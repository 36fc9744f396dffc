"""Extreme but valid parameters and kits: the sound stays finite and one instrument never silences the others."""

from __future__ import annotations

import numpy as np
import pytest
from sound_helpers import impact

from common.kit import Kit, KitObject
from common.messages.sound import SoundDamping
from services.sound.core import SoundCore, SoundSettings


@pytest.mark.parametrize("block", [64, 256, 512])
@pytest.mark.parametrize("instrument", ["snare", "crash", "cowbell"])
def test_the_heaviest_damping_the_panel_allows_keeps_the_kit_sounding(instrument: str, block: int) -> None:
    core = SoundCore(SoundSettings(latency=0.0, block_size=block, record=True))
    # in range (sigma1 <= 1e-3 s), but high modes then lose thousands of nepers per block
    assert core.handle(SoundDamping(instrument=instrument, sigma0=0.0, sigma1=1e-3), 0.0, "panel") == []
    core.handle(impact(1, 0.0103, instrument), 0.0, "t")
    core.handle(impact(2, 0.2, "kick"), 0.0, "t")
    core.render(0.6)
    audio = core.recording()
    core.close()
    # was: NaN from the strike on, for every instrument, for good
    assert np.all(np.isfinite(audio))
    kick = audio[int(0.2 * 48000):int(0.3 * 48000)]
    assert np.max(np.abs(kick)) > 0.05
    struck = audio[int(0.0103 * 48000):int(0.05 * 48000)]
    assert 0.0 < np.max(np.abs(struck)) <= 1.0


@pytest.mark.parametrize("kind", ["membrane", "cymbal", "hihat", "bell"])
def test_a_tiny_kit_object_is_silent_or_sounds_but_never_breaks_the_mix(kind: str) -> None:
    tiny = KitObject(id="tiny", kind=kind, position=(-0.3, 0.5, 0.6), radius=0.005)  # a kit file may say so
    snare = KitObject(id="snare", kind="membrane", position=(0.3, 0.5, 0.6), radius=0.178, depth=0.14)
    core = SoundCore(SoundSettings(latency=0.0), Kit(name="tiny", objects=[tiny, snare], events={}))
    core.handle(impact(1, 0.01, "tiny"), 0.0, "t")
    core.handle(impact(2, 0.2, "snare"), 0.0, "t")
    core.render(0.5)
    audio = core.recording()
    core.close()
    assert np.all(np.isfinite(audio))  # was: NaN from the tiny drum's strike on
    assert np.max(np.abs(audio[int(0.2 * 48000):])) > 0.05  # the snare is heard


def test_an_instrument_whose_output_goes_non_finite_is_stopped_and_the_rest_plays_on(
        caplog: pytest.LogCaptureFixture) -> None:
    core = SoundCore(SoundSettings(latency=0.0))
    crash = core.instruments.instruments["crash"]
    crash.bank.z[:] = np.nan  # whatever path got it there: it must not reach the mix
    crash.bank._live, crash.bank.n_live = True, crash.bank.size
    core.handle(impact(1, 0.2, "snare"), 0.0, "t")
    core.render(0.5)
    audio = core.recording()
    core.close()
    assert np.all(np.isfinite(audio)) and np.max(np.abs(audio[int(0.2 * 48000):])) > 0.05
    assert core.stats.silenced == 1 and "crash produced non-finite samples" in caplog.text
