"""Footboard impacts (``pedal_impacts``) on a kit whose designer renamed the hi-hat, the kick and their pedals: the
hi-hat's pedal (HIHATPEDAL's ``pedal``) sounds the hi-hat's foot chick, the bass pedals the kick, found by the kit's
events whatever the ids (the hi-hat's pedal was voiced as a kick when its id did not hold 'hihat')."""

from __future__ import annotations

import numpy as np
import pytest
from sound_helpers import impact

from common.kit import EventType, Kit, load_kit
from services.sound.core import SoundCore, SoundSettings
from tests.renamed_kits import renamed_kit


def _aliases(kit_name: str, renamed: bool) -> dict[str, tuple[str, str, float]]:
    kit = renamed_kit(kit_name) if renamed else load_kit(kit_name)
    core = SoundCore(SoundSettings(latency=0.0, use_pyo=False, pedal_impacts=True), kit)
    try:
        return dict(core.instruments.aliases)
    finally:
        core.close()


def _render(kit_name: str, instrument: str, zone: str, r: float) -> np.ndarray:
    core = SoundCore(SoundSettings(latency=0.0, use_pyo=False, pedal_impacts=True), renamed_kit(kit_name))
    try:
        core.handle(impact(1, 0.05, instrument, velocity=2.0, r=r, zone=zone), 0.0, "t")
        return core.render(0.4)
    finally:
        core.close()


@pytest.mark.parametrize("kit_name", ["default", "double_pedal", "left_handed"])
def test_the_renamed_pedals_sound_what_they_drive(kit_name: str) -> None:
    bass_r = load_kit(kit_name).events[EventType.BASS].r
    expected = {"bd_pedal": ("bassdrum", "centre", bass_r), "foot_chick": ("hats", "pedal", 0.9)}
    if kit_name == "double_pedal":
        expected["bd_pedal_2"] = ("bassdrum", "centre", bass_r)
    assert _aliases(kit_name, renamed=True) == expected
    shipped = {"kick_pedal": ("kick", "centre", bass_r), "hihat_pedal": ("hihat", "pedal", 0.9)}
    if kit_name == "double_pedal":
        shipped["kick_pedal_left"] = ("kick", "centre", bass_r)
    assert _aliases(kit_name, renamed=False) == shipped  # the shipped kits' as before


def test_a_strike_on_the_renamed_hihat_pedal_is_the_hihats_foot_chick() -> None:
    chick = _render("default", "foot_chick", "centre", 0.5)
    assert np.max(np.abs(chick)) > 0.005
    np.testing.assert_array_equal(chick, _render("default", "hats", "pedal", 0.9))
    assert not np.array_equal(chick, _render("default", "bassdrum", "centre", 0.2))


def _hihat_played_on_its_cymbal(pedal_id: str, kit_name: str = "default") -> dict[str, tuple[str, str, float]]:
    """Aliases of a kit whose HIHATPEDAL names no ``pedal`` (played on the hi-hat itself) and whose hi-hat footboard
    is ``pedal_id``."""
    data = load_kit(kit_name, warn=False).model_dump(mode="json")
    data["events"]["HIHATPEDAL"].update(pedal=None, object="hihat")
    for obj in data["objects"]:
        if obj["id"] == "hihat_pedal":
            obj["id"] = pedal_id
    data["name"] = f"{kit_name}_no_hihat_pedal"
    core = SoundCore(SoundSettings(latency=0.0, use_pyo=False, pedal_impacts=True), Kit.model_validate(data))
    try:
        return dict(core.instruments.aliases)
    finally:
        core.close()


@pytest.mark.parametrize("kit_name", ["default", "double_pedal"])
def test_a_footboard_no_event_names_is_never_the_kick(kit_name: str) -> None:
    """Only the pedals BASS plays sound the kick: a hi-hat footboard HIHATPEDAL does not name keeps the id rule (a
    chick when its id says hihat) or stays silent; it was the kick (980f8db)."""
    bass_r = load_kit(kit_name).events[EventType.BASS].r
    kicks = {"kick_pedal": ("kick", "centre", bass_r)}
    if kit_name == "double_pedal":
        kicks["kick_pedal_left"] = ("kick", "centre", bass_r)
    assert _hihat_played_on_its_cymbal("hihat_pedal", kit_name) == {**kicks, "hihat_pedal": ("hihat", "pedal", 0.9)}
    assert _hihat_played_on_its_cymbal("left_board", kit_name) == kicks
