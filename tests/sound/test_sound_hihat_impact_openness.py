"""A hi-hat stroke sounds as open as its impact says (``Impact.openness``, interaction's map of the plates' gap), not
in three steps: a stroke at a gap between the zone's half and open thresholds sounds between a half-open stroke and
an open one, in every model, rendered offline from the impact interaction sends (before: the sound went by the zone
alone, so every gap from 0.5 to 1.5 mm sounded the same half-open hat). An impact without it (-1: a Pd patch, an
older interaction) goes by its zone, as before."""

from __future__ import annotations

import math

import numpy as np
import pytest

from common.kit import load_kit
from common.messages import Contact, Impact
from services.interaction.core import InteractionCore
from services.interaction.features import ZoneConfig
from services.sound.core import SoundCore, SoundSettings

KIT = load_kit("default", warn=False)
MODELS = ("modal", "synth", "sample")


def _from_interaction(gap: float) -> Impact:
    """The impact interaction sends the sound for a stick stroke meeting the hat's plates ``gap`` apart (the
    contact's openness: the gap above first touch over 25 mm)."""
    contact = Contact(time=0.0, step=0, instrument="hihat", part="right_stick_tip", x=0.0, y=0.0, z=0.9,
                      local_x=0.1, local_y=0.0, local_z=0.0, normal_x=0.0, normal_y=0.0, normal_z=1.0,
                      normal_velocity=3.0, impulse=0.01, normal_force=10.0, openness=gap)
    sent = [o.message for o in InteractionCore(kit=KIT).handle(contact, 0.0, "physics") if o.to == "sound"]
    assert isinstance(sent[0], Impact)
    return sent[0]


def _zone_only(zone: str) -> Impact:
    """The same stroke from a sender without the openness (a Pd patch, an older interaction): its zone alone."""
    return _from_interaction(0.0).model_copy(update={"zone": zone, "openness": -1.0})


def _render(model: str, impact: Impact) -> tuple[np.ndarray, int, float]:
    """The stroke rendered offline (a manual pyo server): the recording, its rate and the hat's openness after."""
    core = SoundCore(SoundSettings(latency=0.0, model=model), KIT)
    try:
        core.handle(impact, 0.0, "interaction")
        x = core.render(0.2)
        return x, core.sample_rate, core.instruments.instruments["hihat"].p.openness
    finally:
        core.close()


def _ring_db(x: np.ndarray, sr: int) -> float:
    """How much the stroke rings: the energy of its 50-100 ms over its first 20 ms', dB."""
    e = np.asarray(x, dtype=np.float64) ** 2
    return 10.0 * math.log10(float(np.sum(e[int(0.05 * sr):int(0.1 * sr)]) / np.sum(e[:int(0.02 * sr)])))


@pytest.mark.parametrize("model", MODELS)
def test_a_stroke_at_a_gap_between_half_and_open_sounds_between_them(model: str) -> None:
    zones = ZoneConfig()
    gap = zones.hihat_half_from + 0.75 * (zones.hihat_open_from - zones.hihat_half_from)  # 0.05: 1.25 mm
    stroke = _from_interaction(gap)
    assert stroke.zone == "half" and stroke.openness == pytest.approx(0.75)
    x, sr, openness = _render(model, stroke)
    assert openness == pytest.approx(0.75)
    half, open_ = (_ring_db(*_render(model, _zone_only(z))[:2]) for z in ("half", "open"))
    mid = _ring_db(x, sr)
    span = open_ - half
    assert abs(span) > 0.3, f"{model}: half and open ring alike ({half:.2f}, {open_:.2f} dB)"
    # strictly between, not at either end: at least a tenth of the way from each
    assert 0.1 < (mid - half) / span < 0.9, f"{model}: half {half:.2f} / gap {mid:.2f} / open {open_:.2f} dB"


@pytest.mark.parametrize(("gap", "zone"), [(0.0, "closed"), (0.41, "open")])
def test_closed_and_open_notes_sound_as_their_zones_did(gap: float, zone: str) -> None:
    """The planner's closed note (plates clamped) and open note (10 mm) map to exactly the openness their zones
    were played at (0 and 1): the same samples (the demo's WAV did not change)."""
    a, _, oa = _render("modal", _from_interaction(gap))
    b, _, ob = _render("modal", _zone_only(zone))
    assert oa == ob and np.array_equal(a, b)


def test_an_impact_without_openness_goes_by_its_zone_and_the_chick_closes_the_hat() -> None:
    assert _render("modal", _zone_only("half"))[2] == 0.5
    assert _render("modal", _zone_only("bow"))[2] == KIT.object("hihat").opening  # unchanged: the kit's rest
    chick = _from_interaction(0.41).model_copy(update={"part": "hihat_top"})  # the top plate closing: a chick
    assert chick.openness == 1.0 and _render("modal", chick)[2] == 0.0
