"""A hi-hat impact's zone says how open the simulated hi-hat was when the stick met it (the contact's
``openness``, physics' gap between the plates): ``open``, ``half`` or ``closed`` (before: always bow, edge or
bell, and the sound played every stroke at the kit's rest opening). A contact without the field (an older
physics, a Pd patch: 17 arguments) still decodes, and its hi-hat impact keeps the cymbal zones."""

from __future__ import annotations

import pytest

from common.kit import load_kit
from common.messages import Contact
from common.messages.codec import decode, encode, encode_raw
from services.interaction.detect import ImpactOnset, Segmenter
from services.interaction.features import ZoneConfig, zone


def _contact(openness: float = -1.0, instrument: str = "hihat", t: float = 1.0, step: int = 1000) -> Contact:
    return Contact(time=t, step=step, instrument=instrument, part="right_stick_tip", x=0.0, y=0.0, z=0.9,
                   local_x=0.1, local_y=0.0, local_z=0.0, normal_x=0.0, normal_y=0.0, normal_z=1.0,
                   normal_velocity=3.0, impulse=0.01, normal_force=10.0, openness=openness)


def _zone_of(c: Contact) -> str:
    seg = Segmenter(load_kit("default", warn=False))
    onsets = [e for e in seg.contact(c, c.time) if isinstance(e, ImpactOnset)]
    assert len(onsets) == 1
    return onsets[0].impact.zone


@pytest.mark.parametrize(("openness", "expected"), [(0.0, "closed"), (0.01, "closed"), (0.03, "half"),
                                                    (0.09, "open"), (0.6, "open")])
def test_a_hihat_impact_is_open_half_or_closed_from_the_contact_openness(openness: float, expected: str) -> None:
    assert _zone_of(_contact(openness)) == expected


def test_a_hihat_contact_without_openness_keeps_the_cymbal_zones() -> None:
    assert _zone_of(_contact(-1.0)) == "bow"


def test_the_thresholds_are_the_zone_config_s() -> None:
    hihat = load_kit("default", warn=False).object("hihat")
    zones = ZoneConfig(hihat_half_from=0.1, hihat_open_from=0.3)
    assert [zone(hihat, 0.6, zones, o) for o in (0.05, 0.1, 0.29, 0.3)] == ["closed", "half", "half", "open"]


def test_another_instrument_ignores_openness() -> None:
    kit = load_kit("default", warn=False)
    ride = next(o for o in kit.objects if o.kind == "cymbal")
    assert zone(ride, 0.6, ZoneConfig(), 0.5) == zone(ride, 0.6, ZoneConfig()) == "bow"


def test_an_older_contact_without_openness_decodes_and_a_newer_one_with_more_arguments_too() -> None:
    args = _contact(0.25).to_args()
    assert len(args) == 18 and Contact.from_args(args).openness == pytest.approx(0.25)
    older = Contact.from_args(args[:-1])  # a sender from before the field: 17 arguments
    assert older.openness == -1.0 and older.normal_force == pytest.approx(10.0)
    newer = Contact.from_args([*args, 1.0, "x"])  # fields appended since: ignored
    assert newer.openness == pytest.approx(0.25)
    with pytest.raises(ValueError, match="wrong_arity"):
        Contact.from_args(args[:-2])  # a field missing that was never optional
    on_the_wire = decode(encode_raw(Contact.ADDRESS, args[:-1]))  # an older physics' datagram
    assert not on_the_wire.errors and [m.openness for m in on_the_wire.messages] == [-1.0]  # type: ignore[attr-defined]
    assert [m.openness for m in decode(encode(_contact(0.5))).messages] == [0.5]  # type: ignore[attr-defined]
