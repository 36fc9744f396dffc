"""Live parameters over OSC: applied when valid, rejected with a reason and counted when not."""

from __future__ import annotations

import numpy as np
from sound_helpers import impact

from common.bus import MemoryBus
from common.messages import DropReason, encode_raw
from common.messages.sound import (
    SoundDamping,
    SoundDensity,
    SoundLatency,
    SoundLevel,
    SoundModel,
    SoundModes,
    SoundOpenness,
    SoundRadius,
    SoundRejected,
    SoundTension,
)
from services.sound.core import SoundCore, SoundSettings
from services.sound.instruments import Membrane


def wire(core: SoundCore) -> tuple[MemoryBus, list[SoundRejected]]:
    """Put the core on an in-memory bus (decoding validates as on the wire); collect replies to 'panel'."""
    bus = MemoryBus()
    ep = bus.endpoint("sound")
    panel = bus.endpoint("panel")
    replies: list[SoundRejected] = []

    def on_message(message: object, source: str) -> None:
        for out in core.handle(message, core.now, source):  # type: ignore[arg-type]
            ep.send(out.message, source if out.to == "reply" else out.to)

    ep.set_handler(on_message)
    panel.set_handler(lambda m, s: replies.append(m) if isinstance(m, SoundRejected) else None)
    return bus, replies


def test_out_of_range_values_are_dropped_with_a_reason_and_counted() -> None:
    core = SoundCore(SoundSettings(use_pyo=False))
    bus, _ = wire(core)
    before = core.instruments.instruments["snare"].p.tension
    bus.post(encode_raw("/batteur/sound/tension", ["snare", -5.0]), "sound", "panel")
    bus.post(encode_raw("/batteur/sound/damping", ["snare", 10.0, 1.0]), "sound", "panel")  # sigma1 > 1e-3
    bus.post(encode_raw("/batteur/sound/model", ["snare", "granular"]), "sound", "panel")
    bus.post(encode_raw("/batteur/sound/modes", ["snare", 1.5]), "sound", "panel")  # not an integer
    bus.post(encode_raw("/batteur/sound/level", ["snare"]), "sound", "panel")  # missing argument
    stats = bus.endpoints["sound"].stats
    assert stats.dropped[DropReason.OUT_OF_RANGE] == 3
    assert stats.dropped[DropReason.WRONG_TYPE] == 1
    assert stats.dropped[DropReason.WRONG_ARITY] == 1
    assert core.instruments.instruments["snare"].p.tension == before  # nothing clamped, nothing applied


def test_values_an_instrument_cannot_take_are_rejected_with_a_reply() -> None:
    core = SoundCore(SoundSettings(use_pyo=False))
    bus, replies = wire(core)
    panel = bus.endpoints["panel"]
    panel.send(SoundTension(instrument="ride", value=3000.0), "sound")  # cymbals have no tension
    panel.send(SoundRadius(instrument="gong", value=0.3), "sound")  # no such instrument
    panel.send(SoundOpenness(instrument="snare", value=0.5), "sound")  # only hi-hats open
    # every mode above Nyquist
    panel.send(SoundTension(instrument="hightom", value=100000.0), "sound")
    panel.send(SoundDensity(instrument="hightom", value=0.011), "sound")
    panel.send(SoundRadius(instrument="hightom", value=0.021), "sound")
    assert [r.address for r in replies] == [
        "/batteur/sound/tension", "/batteur/sound/radius", "/batteur/sound/openness", "/batteur/sound/radius",
    ]
    assert "cymbal instrument 'ride' takes no /batteur/sound/tension (it takes: " in replies[0].reason
    assert "/batteur/sound/thickness" in replies[0].reason and "n_modes" not in replies[0].reason
    assert "no instrument 'gong'" in replies[1].reason
    assert "Nyquist" in replies[3].reason
    assert core.stats.rejected_total == 4
    # the accepted tension did change the drum, the rejected radius did not
    tom = core.instruments.instruments["hightom"]
    assert tom.p.tension == 100000.0 and abs(tom.p.density - 0.011) < 1e-6 and tom.p.radius > 0.1


def test_valid_parameters_change_the_sound_live() -> None:
    core = SoundCore(SoundSettings(use_pyo=False, latency=0.0))
    bus, replies = wire(core)
    panel = bus.endpoints["panel"]
    snare = core.instruments.instruments["snare"]
    assert isinstance(snare, Membrane)
    f01 = snare.bank.freq[0]
    panel.send(SoundTension(instrument="snare", value=4 * snare.p.tension), "sound")
    assert np.isclose(snare.bank.freq[0], 2 * f01)
    panel.send(SoundModes(instrument="snare", value=40), "sound")
    assert snare.modes.freq.shape[0] == 40
    panel.send(SoundDamping(instrument="snare", sigma0=50.0, sigma1=0.0), "sound")
    assert np.allclose(snare.bank.decay[: snare.n_head], 50.0)
    panel.send(SoundLevel(instrument="snare", gain_db=-6.0), "sound")
    assert np.isclose(snare.gain, 10 ** (-6 / 20))
    panel.send(SoundModel(instrument="snare", model="sample"), "sound")
    assert snare.model == "sample"
    panel.send(SoundLatency(value=0.1), "sound")
    assert abs(core.scheduler.latency - 0.1) < 1e-6  # float32 on the wire
    assert replies == [] and core.stats.rejected_total == 0


def test_hihat_openness_chokes_a_ringing_hat() -> None:
    core = SoundCore(SoundSettings(latency=0.0, use_pyo=False))
    core.handle(impact(1, 0.0, "hihat", zone="open", velocity=4.0, r=0.7), 0.0, "t")
    core.render(0.3)
    open_level = np.max(np.abs(core.render(0.35)))
    core.handle(SoundOpenness(instrument="hihat", value=0.0), core.now, "panel")
    core.render(0.5)
    closed_level = np.max(np.abs(core.render(0.55)))
    assert closed_level < 0.05 * open_level
    # and an open hat keeps ringing much longer than a closed one
    a = SoundCore(SoundSettings(latency=0.0, use_pyo=False))
    a.handle(impact(1, 0.0, "hihat", zone="closed", velocity=4.0, r=0.7), 0.0, "t")
    a.render(0.3)
    assert np.max(np.abs(a.render(0.35))) < 0.1 * open_level


def test_unknown_instrument_impacts_are_counted_not_played() -> None:
    core = SoundCore(SoundSettings(use_pyo=False, latency=0.0))
    core.handle(impact(1, 0.0, "gong"), 0.0, "t")
    core.render(0.1)
    assert core.stats.unknown_instrument == 1 and core.stats.strikes == 0
