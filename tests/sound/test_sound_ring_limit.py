"""An undamped instrument (/batteur/sound/damping 0 0, in range) rings at most MAX_T60_S, then falls silent."""

from __future__ import annotations

import numpy as np
from sound_helpers import SR, impact, one_drum_kit

from common.messages.sound import SoundDamping
from services.sound.core import SoundCore, SoundSettings
from services.sound.modal_bank import MAX_T60_S, MIN_DECAY_PER_S, ModeSet


def test_an_undamped_drum_decays_60_db_in_the_longest_ring_and_then_stops() -> None:
    core = SoundCore(SoundSettings(latency=0.0, use_pyo=False), one_drum_kit())
    try:
        assert core.handle(SoundDamping(instrument="drum", sigma0=0.0, sigma1=0.0), 0.0, "panel") == []
        core.handle(impact(1, 0.0), 0.0, "t")
        core.render(MAX_T60_S + 1.5)
        audio = core.recording()
        drum = core.instruments.instruments["drum"]
        early = np.max(np.abs(audio[int(0.5 * SR):int(1.5 * SR)]))
        late = np.max(np.abs(audio[int((MAX_T60_S + 0.5) * SR):]))
        # was: no decay at all (the same level at 31 s as at 1 s, and for ever)
        assert 20 * np.log10(late / early) < -50.0
        core.render(3.0 * MAX_T60_S)
        assert not drum.sounding  # the bank dropped it below its floor: it costs nothing any more
        assert core.stats.ring_limited == 1 and core.rejected_total == 0  # applied, counted, not refused
    finally:
        core.close()


def test_strikes_on_an_undamped_mode_add_up_to_a_bounded_level() -> None:
    bank = ModeSet(SR, 256)
    bank.set_modes([375.0], [0.0])  # 128 samples a period: every block starts in phase
    out = np.zeros(256, dtype=np.float32)
    for i in range(SR // 256 * 200):  # a strike a second for 200 s, always in phase
        if i % (SR // 256) == 0:
            bank.strike(np.array([1.0 + 0j]), 0)
        bank.process(out)
    # was: 200 (each strike added to an amplitude that never decayed); now a geometric series
    assert abs(bank.z[0]) < 1.0 / (1.0 - np.exp(-MIN_DECAY_PER_S)) + 1.0
    assert bank.slowed == 1 and bank.decay[0] == MIN_DECAY_PER_S


def test_no_mode_of_the_default_kit_reaches_the_limit() -> None:
    core = SoundCore(SoundSettings(use_pyo=False))
    try:
        hat = core.instruments.instruments["hihat"]
        hat.set_param("openness", value=1.0)  # the least damped the hi-hat gets
        for inst in core.instruments.instruments.values():
            assert inst.bank.slowed == 0, inst.id  # so a default render is exactly what it was
    finally:
        core.close()
