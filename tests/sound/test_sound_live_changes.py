"""Live parameter changes in the node: computed off the render loop, swapped in whole, in message order."""

from __future__ import annotations

import argparse
import threading
from collections.abc import Iterator

import numpy as np
import pytest
from sound_helpers import impact, one_drum_kit, settle

from common.config import load_settings
from common.kit import load_kit
from common.messages.sound import SoundDensity, SoundLevel, SoundModes, SoundRadius, SoundRejected, SoundTension
from services.sound import membrane
from services.sound.core import SoundCore, SoundSettings
from services.sound.node import make_core

PANEL = "127.0.0.1:9000"


def _core(background: bool) -> SoundCore:
    return SoundCore(SoundSettings(latency=0.01, use_pyo=False, record=False, background_rebuilds=background),
                     one_drum_kit())


@pytest.fixture
def live() -> Iterator[SoundCore]:
    core = _core(True)
    yield core
    core.close()


@pytest.fixture
def offline() -> Iterator[SoundCore]:
    core = _core(False)
    yield core
    core.close()


def _same_modes(a: SoundCore, b: SoundCore) -> None:
    x, y = a.instruments.instruments["drum"], b.instruments.instruments["drum"]
    assert x.p == y.p
    assert np.array_equal(x.bank.freq, y.bank.freq) and np.array_equal(x.bank.decay, y.bank.decay)
    assert np.array_equal(x.bank._table, y.bank._table) and np.array_equal(x.gains, y.gains)


def test_a_modes_change_is_not_computed_in_the_loop_and_lands_as_if_applied_at_once(live: SoundCore,
                                                                                    offline: SoundCore) -> None:
    for core in (live, offline):
        core.handle(impact(1, 0.0), 0.0, "t")
        core.render(0.1)
    drum = live.instruments.instruments["drum"]
    before = drum.bank.size
    assert live.handle(SoundModes(instrument="drum", value=3000), live.now, PANEL) == []
    # was: the loop computed the Bessel-zero table there and then (seconds at 20,000 modes)
    assert drum.bank.size == before and drum.p.n_modes == 160  # the old modes play on meanwhile
    assert drum.sounding
    offline.handle(SoundModes(instrument="drum", value=3000), offline.now, PANEL)
    assert settle(live) == []
    _same_modes(live, offline)
    assert drum.bank.size > 3000 and drum.sounding  # the ringing went on through the swap
    assert np.any(drum.bank.z[:before] != 0)


def test_changes_behind_a_background_one_keep_their_order(live: SoundCore, offline: SoundCore) -> None:
    changes = [SoundModes(instrument="drum", value=2500), SoundLevel(instrument="drum", gain_db=-6.0),
               SoundTension(instrument="drum", value=5000.0), SoundModes(instrument="drum", value=900)]
    for core in (live, offline):
        for message in changes:
            assert core.handle(message, core.now, PANEL) == []
    settle(live)
    _same_modes(live, offline)
    assert live.instruments.instruments["drum"].p.level_db == -6.0


def test_a_background_change_that_cannot_be_taken_is_refused_to_its_sender(live: SoundCore,
                                                                           offline: SoundCore) -> None:
    # each in range, but together every mode of the head is above Nyquist
    changes = [SoundTension(instrument="drum", value=100000.0), SoundDensity(instrument="drum", value=0.011),
               SoundRadius(instrument="drum", value=0.021)]
    replies = [out for message in changes for out in offline.handle(message, 0.0, "reply")]
    assert [r.message.address for r in replies] == ["/batteur/sound/radius"]
    for message in changes:
        assert live.handle(message, live.now, PANEL) == []
    replies = settle(live)
    assert len(replies) == 1 and replies[0].to == PANEL and isinstance(replies[0].message, SoundRejected)
    assert replies[0].message.address == "/batteur/sound/radius" and "Nyquist" in replies[0].message.reason
    assert live.stats.rejected["/batteur/sound/radius"] == 1
    _same_modes(live, offline)  # the radius stayed as it was, the other two applied


def test_a_hihat_opened_by_a_strike_during_a_change_stays_open() -> None:
    core = SoundCore(SoundSettings(latency=0.0, use_pyo=False, record=False, background_rebuilds=True))
    try:
        core.step(0.0)
        hat = core.instruments.instruments["hihat"]
        core.handle(SoundModes(instrument="hihat", value=1400), core.now, PANEL)
        core.handle(impact(1, core.now, "hihat", zone="open"), core.now, "t")
        core.step(core.now + 0.02)  # the strike opens the hat (a rebuild of its own) while the change runs
        settle(core)
        assert hat.p.openness == 1.0 and hat.p.n_modes == 1400
    finally:
        core.close()


def test_the_live_node_changes_in_the_background_and_offline_renders_do_not() -> None:
    settings = load_settings({"role": "sound", "discovery": False, "clock_master": "self"})
    extra = argparse.Namespace(kit="default", wav=None, device="none", model="modal", block_size=256, channels=1,
                               reverb=0.0)
    core = make_core(settings, extra)
    try:
        assert core.settings.background_rebuilds
    finally:
        core.close()
    assert not SoundSettings().background_rebuilds


def test_a_large_bessel_table_from_a_worker_thread_is_the_same_bits(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(membrane, "_TABLES", [])
    found: list[np.ndarray] = []
    worker = threading.Thread(target=lambda: found.append(membrane.bessel_table(90, 30)))  # over 2,000 zeros
    worker.start()
    worker.join(120)
    monkeypatch.setattr(membrane, "_TABLES", [])
    here = membrane.bessel_table(90, 30)
    assert found and found[0].shape == (91, 30) and np.array_equal(found[0], here)
    # and a smaller table sliced from it is the table computed at its own size
    small = membrane.bessel_table(37, 13)
    monkeypatch.setattr(membrane, "_TABLES", [])
    assert np.array_equal(small, membrane.bessel_table(37, 13))


def test_the_default_kit_renders_the_same_with_background_changes_on() -> None:
    kit = load_kit("default")
    audio = []
    for background in (False, True):
        core = SoundCore(SoundSettings(latency=0.0, background_rebuilds=background), kit)
        try:
            for seq, (name, t) in enumerate([("snare", 0.01), ("kick", 0.1), ("ride", 0.2), ("hihat", 0.3)]):
                core.handle(impact(seq, t, name), 0.0, "t")
            core.render(0.6)
            audio.append(core.recording())
        finally:
            core.close()
    assert np.array_equal(audio[0], audio[1])
