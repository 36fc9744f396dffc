"""The master gain comes before the soft limiter: a boost is limited softly, not clipped; a change glides."""

from __future__ import annotations

import numpy as np
import pytest
from sound_helpers import impact

from common.kit import EventType, load_kit
from common.messages.sound import SoundMaster
from services.sound.core import MASTER_RAMP_S, SoundCore, SoundSettings

SNARE = load_kit("default").events[EventType.SNARE]


def _snare(velocity: float, master_db: float) -> np.ndarray:
    core = SoundCore(SoundSettings(latency=0.0, master_db=master_db))
    try:
        core.handle(impact(1, 0.0, "snare", velocity=velocity, r=SNARE.r, theta=SNARE.theta), 0.0, "t")
        core.render(0.3)
        return core.recording()
    finally:
        core.close()


def test_a_boosted_master_limits_a_hard_strike_instead_of_clipping_it() -> None:
    audio = _snare(8.0, 6.0)  # a hard stroke, the master 6 dB up: 2.3 dB over full scale before the limiter
    assert np.max(np.abs(audio)) > 0.95  # loud, limited
    # was: the limiter came before the master gain, and the final clip cut 59 samples flat at full scale
    assert np.count_nonzero(np.abs(audio) >= 1.0 - 1e-6) == 0
    quiet = _snare(2.0, 6.0)  # below the knee: exactly twice the unboosted strike, as before
    np.testing.assert_allclose(quiet, _snare(2.0, 0.0) * 10 ** (6 / 20), rtol=1e-4, atol=1e-6)


@pytest.mark.parametrize("use_pyo", [False, True])
def test_a_master_change_glides_over_the_ramp(use_pyo: bool) -> None:
    """With pyo's graph (its SigTo glides) and without it (the numpy master: it stepped until 7 Dec; with pyo
    alone this test passed before the glide was written)."""
    renders, start = [], 0
    for change in (False, True):
        core = SoundCore(SoundSettings(latency=0.0, use_pyo=use_pyo))
        try:
            core.handle(impact(1, 0.0, "floortom", velocity=2.0), 0.0, "t")
            core.render(0.1)
            start = core.next_sample  # the change lands on the next block's first sample
            if change:
                core.handle(SoundMaster(gain_db=-20.0, reverb=0.0), core.now, "t")
            core.render(0.2)
            renders.append(core.recording())
        finally:
            core.close()
    free, turned = renders
    ramp = int(MASTER_RAMP_S * 48000)
    np.testing.assert_array_equal(turned[:start], free[:start])
    ok = np.abs(free) > 1e-3
    ratio = np.where(ok, turned / np.where(ok, free, 1.0), np.nan)
    gliding = ratio[start:start + ramp][ok[start:start + ramp]]
    assert np.all(np.diff(gliding) <= 1e-4) and gliding[0] > 0.95  # no step: down a little each sample
    np.testing.assert_allclose(ratio[start + ramp:][ok[start + ramp:]], 0.1, rtol=1e-3)
