"""An impact's zone no instrument knows (a typo) is dropped and counted, not played as a centre stroke; what a
kit object is (kick, snare, ride ...) comes from the kit's events, its id only when they do not say."""

from __future__ import annotations

import numpy as np
import pytest
from sound_helpers import impact

from common.kit import ZONES, EventSpec, EventType, Kit, KitObject, Limb, load_kit
from services.sound.core import SoundCore, SoundSettings
from services.sound.instruments import drum_role


def test_an_impact_with_an_unknown_zone_is_dropped_and_counted() -> None:
    core = SoundCore(SoundSettings(use_pyo=False, latency=0.0))
    try:
        core.handle(impact(1, 0.0, "snare", zone="banana"), 0.0, "t")
        core.handle(impact(2, 0.0, "snare", zone="rimm"), 0.0, "t")
        assert np.max(np.abs(core.render(0.2))) == 0.0  # not a centre stroke
        assert core.stats.unknown_zone == 2 and core.stats.strikes == 0 and core.rejected_total == 2
        for seq, zone in enumerate(sorted(ZONES), start=3):  # every zone the services send still plays
            core.handle(impact(seq, core.now, "hihat" if zone in ("open", "half", "closed", "pedal") else "snare",
                               zone=zone), core.now, "t")
        core.render(core.now + 0.1)
        assert core.stats.strikes == len(ZONES) and core.stats.unknown_zone == 2
    finally:
        core.close()


def test_the_unknown_zone_is_said(caplog: pytest.LogCaptureFixture) -> None:
    core = SoundCore(SoundSettings(use_pyo=False, latency=0.0))
    try:
        core.handle(impact(1, 0.0, "snare", zone="rimm"), 0.0, "panel")
    finally:
        core.close()
    said = "dropped an impact from panel on snare: no zone 'rimm' (zones: bell, bow, centre, closed, edge"
    assert said in caplog.text


def _kit(drum_id: str, event: EventType | None, pitch: int | None = None) -> Kit:
    drum = KitObject(id=drum_id, kind="membrane", position=(0.0, 0.6, 0.3), radius=0.25, depth=0.35)
    events = {} if event is None else {event: EventSpec(object=drum_id, r=0.2, preferred=Limb.RIGHT_HAND,
                                                        min_time_gap=0.05)}
    notes = {} if pitch is None else {pitch: drum_id}
    return Kit(name="one", objects=[drum], events=events, note_objects=notes)


def _lowest_hz(kit: Kit) -> float:
    core = SoundCore(SoundSettings(use_pyo=False), kit)
    try:
        inst = next(iter(core.instruments.instruments.values()))
        return float(inst.bank.freq[0])
    finally:
        core.close()


def test_a_kick_named_bd_sounds_as_a_kick() -> None:
    kick = _lowest_hz(_kit("kick", None))
    assert drum_role(_kit("bd", EventType.BASS), _kit("bd", EventType.BASS).objects[0]) == "kick"
    assert _lowest_hz(_kit("bd", EventType.BASS)) == kick  # the kit plays BASS on it
    assert _lowest_hz(_kit("bd", None)) > 1.5 * kick  # nothing says: a tom of its size, as before
    assert _lowest_hz(_kit("bd", None, pitch=36)) == kick  # a General MIDI kick note on it says it too
    # the kit's events win over the id's words: a drum named kick played as a snare is a snare
    assert drum_role(_kit("kick", EventType.SNARE), _kit("kick", EventType.SNARE).objects[0]) == "snare"


def test_an_object_played_as_two_instruments_falls_back_to_its_id() -> None:
    drum = KitObject(id="bd", kind="membrane", position=(0.0, 0.6, 0.3), radius=0.25)
    spec = EventSpec(object="bd", r=0.2, preferred=Limb.RIGHT_HAND, min_time_gap=0.05)
    kit = Kit(name="odd", objects=[drum], events={EventType.BASS: spec, EventType.FLOORTOM: spec})
    assert drum_role(kit, drum) == "bd"
    snare_and_rim = Kit(name="s", objects=[drum], events={EventType.SNARE: spec, EventType.RIM: spec})
    assert drum_role(snare_and_rim, drum) == "snare"  # one instrument, two events


def test_a_kit_event_with_a_zone_the_sound_does_not_play_is_refused_at_load() -> None:
    """Every stroke of it would be dropped by the sound service (counted, but the kit loaded without a word)."""
    drum = KitObject(id="sn", kind="membrane", position=(0.0, 0.6, 0.3), radius=0.18)
    with pytest.raises(ValueError) as caught:
        Kit(name="typo", objects=[drum], events={EventType.SNARE: EventSpec(
            object="sn", r=0.2, zone="rimm", preferred=Limb.RIGHT_HAND, min_time_gap=0.05)})
    said = str(caught.value)
    assert "event SNARE: no zone 'rimm' (zones: bell, bow, centre, closed, edge, half, open, pedal, rim, " in said


@pytest.mark.parametrize("name", ["default", "double_pedal", "left_handed"])
def test_the_shipped_kits_events_use_zones_the_sound_plays(name: str) -> None:
    kit = load_kit(name)
    assert kit.events and all(spec.zone in ZONES for spec in kit.events.values())
