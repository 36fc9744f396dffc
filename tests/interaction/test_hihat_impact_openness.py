"""A hi-hat impact carries how open the hat sounds (``Impact.openness``, 0 closed ... 1 open), mapped by interaction
from the plates' simulated gap at the contact (features.hihat_openness: 0 up to ``hihat_openness_from``, 1 from
``hihat_openness_full``, linear between); the zone keeps its own thresholds. Before: only the zone, so the sound
played every stroke at one of three openness steps (1, 0.5, 0). Another instrument, or a contact without the gap,
carries -1. An impact from a sender without the field (12 arguments: [batteur-strike], an older interaction)
decodes with -1."""

from __future__ import annotations

import pytest

from common.kit import load_kit
from common.messages import Contact, Impact
from common.messages.codec import decode, encode, encode_raw, parse_packet
from common.messages.interaction import MessageAdd
from services.interaction.config import DetectionConfig, InteractionConfig
from services.interaction.core import InteractionCore
from services.interaction.features import ZoneConfig, hihat_openness

KIT = load_kit("default", warn=False)


def _contact(gap: float, instrument: str = "hihat") -> Contact:
    return Contact(time=1.0, step=1000, instrument=instrument, part="right_stick_tip", x=0.0, y=0.0, z=0.9,
                   local_x=0.1, local_y=0.0, local_z=0.0, normal_x=0.0, normal_y=0.0, normal_z=1.0,
                   normal_velocity=3.0, impulse=0.01, normal_force=10.0, openness=gap)


def _impact_to_sound(gap: float, instrument: str = "hihat", config: InteractionConfig | None = None) -> Impact:
    core = InteractionCore(kit=KIT, config=config)
    out = [o.message for o in core.handle(_contact(gap, instrument), 1.0, "physics") if o.to == "sound"]
    sent = [m for m in out if isinstance(m, Impact)]
    assert sent and len(sent) == len(out)
    assert len({m.openness for m in sent}) == 1  # every redundant copy the same
    return sent[0]


@pytest.mark.parametrize(("gap", "zone", "openness"), [
    (0.0, "closed", 0.0),  # the plates clamped: exactly the closed stroke's openness, as before
    (0.019, "closed", 0.0),  # every closed zone's gap: 0
    (0.03, "half", 0.25),
    (0.04, "half", 0.5),
    (0.05, "half", 0.75),
    (0.06, "open", 1.0),
    (0.41, "open", 1.0),  # the planner's open note on the default kit (10 mm): fully open
])
def test_a_hihat_impact_carries_the_openness_mapped_from_the_gap(gap: float, zone: str, openness: float) -> None:
    impact = _impact_to_sound(gap)
    assert impact.zone == zone
    assert impact.openness == pytest.approx(openness, abs=1e-6)


def test_openness_rises_with_the_gap_between_half_and_open_without_steps() -> None:
    hihat = KIT.object("hihat")
    zones = ZoneConfig()
    gaps = [zones.hihat_half_from + k * 0.001 for k in range(41)]  # 0.5 mm .. 1.5 mm
    values = [hihat_openness(hihat, g, zones) for g in gaps]
    assert values[0] == pytest.approx(0.0, abs=1e-9) and values[-1] == pytest.approx(1.0)
    steps = [b - a for a, b in zip(values, values[1:], strict=False)]
    assert all(0.0 < s < 0.03 for s in steps), steps  # strictly rising, 0.025 per 0.001 of gap: no jump


def test_another_instrument_or_a_contact_without_the_gap_carries_minus_one() -> None:
    assert _impact_to_sound(0.5, instrument="snare").openness == -1.0
    hat = _impact_to_sound(-1.0)  # an older physics' contact: no gap
    assert hat.openness == -1.0 and hat.zone == "bow"


def test_the_map_is_the_zone_config_s_and_the_zone_keeps_its_thresholds() -> None:
    zones = ZoneConfig(hihat_openness_from=0.0, hihat_openness_full=0.5)
    config = InteractionConfig(detection=DetectionConfig(zones=zones))
    impact = _impact_to_sound(0.03, config=config)
    assert impact.zone == "half" and impact.openness == pytest.approx(0.06)
    with pytest.raises(ValueError, match="hihat_openness_full .* must be above hihat_openness_from"):
        ZoneConfig(hihat_openness_from=0.1, hihat_openness_full=0.1)


def test_a_registered_message_can_send_the_openness() -> None:
    """A Pd synth or a DAW gets it through a registered message (docs/interaction.md), as any feature."""
    core = InteractionCore(kit=KIT)
    add = MessageAdd(name="pd", to="127.0.0.1:9999", address="/pd/hat", instruments="hihat", when="onset",
                     specs=("zone", "openness"))
    assert core.handle(add, 0.0, "pd") == []
    out = [o for o in core.handle(_contact(0.05), 1.0, "physics") if o.to == "127.0.0.1:9999"]
    assert len(out) == 1
    assert parse_packet(encode(out[0].message))[0].args == ["half", pytest.approx(0.75)]


def test_an_impact_from_a_sender_without_openness_decodes_and_one_from_a_newer_sender_too() -> None:
    args = _impact_to_sound(0.05).to_args()
    assert len(args) == 13 and Impact.from_args(args).openness == pytest.approx(0.75)
    older = Impact.from_args(args[:-1])  # [batteur-strike], an older interaction: 12 arguments
    assert older.openness == -1.0 and older.zone == "half" and older.part == "right_stick_tip"
    assert Impact.from_args([*args, 1.0, "x"]).openness == pytest.approx(0.75)  # fields appended since: ignored
    with pytest.raises(ValueError, match="wrong_arity"):
        Impact.from_args(args[:-2])  # a field missing that was never optional
    on_the_wire = decode(encode_raw(Impact.ADDRESS, args[:-1]))  # an older sender's datagram
    assert not on_the_wire.errors and [m.openness for m in on_the_wire.messages] == [-1.0]  # type: ignore[attr-defined]
