"""An open hi-hat stops ringing once its plates close, whatever closes them and whichever sound model plays it.

* The foot letting the pedal down after an open note meets the plates at ~0 m/s: physics reports a plate contact
  too slow for a chick (a touch, no impact) and for 10 ms only. Interaction makes it a press of the plates
  (/batteur/damping, part ``hihat_rattle`` or ``hihat_top``) and the sound closes the hat on it, silently (before:
  interaction sent nothing, the sound ignored plate presses, and the open hat rang on for over 2 s).
* The ``synth`` and ``sample`` models choke the open hat's voices when its openness drops (a closed stroke, a chick,
  the plates closing), as the modal model's damping does (before: they rang on as if alone).
"""

from __future__ import annotations

import numpy as np
import pytest

from common.kit import load_kit
from common.messages import Contact, Impact
from common.messages.interaction import Damping
from services.interaction.detect import DampingChange, ImpactOnset, Segmenter
from services.sound.core import SoundCore, SoundSettings

OPEN_AT_S = 0.1


def _stroke(seq: int, t: float, zone: str, part: str = "right_stick_tip") -> Impact:
    return Impact(seq=seq, time=t, instrument="hihat", zone=zone, r=0.6, theta=0.0, velocity=3.0, impulse=0.01,
                  peak_force=10.0, duration=0.002, part=part)


def _plates(seq: int, t: float, state: int, part: str = "hihat_rattle") -> Damping:
    """The plates coming to rest together (state 1) as interaction reports a let-down, and the report's end."""
    return Damping(seq=seq, time=t, instrument="hihat", part=part, state=state, zone="closed", r=0.0, theta=0.0,
                   force=0.06 if state else 0.0)


def _render(model: str, messages: list[Impact | Damping], until_s: float) -> tuple[np.ndarray, SoundCore]:
    core = SoundCore(SoundSettings(use_pyo=False, latency=0.0, model=model), load_kit("default", warn=False))
    try:
        for m in messages:
            core.handle(m, 0.0, "test")
        x = np.asarray(core.render(until_s), dtype=np.float64)
    finally:
        core.close()
    return (x.mean(axis=1) if x.ndim > 1 else x), core


def _energy(x: np.ndarray, sr: int, a_s: float, b_s: float) -> float:
    return float(np.sum(x[int(a_s * sr):int(b_s * sr)] ** 2))


# ----------------------------------------------------------------------------------------------- the plates close


@pytest.mark.parametrize("part", ["hihat_rattle", "hihat_top"])
def test_the_plates_closing_slowly_after_an_open_stroke_choke_the_modal_hat_silently(part: str) -> None:
    close_s = OPEN_AT_S + 0.215  # as ring.py's let-down: the plates meet ~215 ms after the open note
    alone, _ = _render("modal", [_stroke(0, OPEN_AT_S, "open")], close_s + 1.1)
    closed, core = _render("modal", [_stroke(0, OPEN_AT_S, "open"), _plates(0, close_s, 1, part),
                                     _plates(1, close_s + 0.01, 0, part)], close_s + 1.1)
    sr = core.sample_rate
    ring_alone = _energy(alone, sr, close_s + 0.5, close_s + 1.0)
    assert ring_alone > 0.0
    assert _energy(closed, sr, close_s + 0.5, close_s + 1.0) < 1e-4 * ring_alone  # 40 dB down at least
    # silent: nothing louder than the open hat alone from the close on (no chick, no click), the same before it
    start = int(close_s * sr)
    assert np.array_equal(closed[:start - core.block], alone[:start - core.block])
    def block_rms(x: np.ndarray) -> np.ndarray:  # the 40 blocks from the close's
        return np.sqrt(np.mean(x[start - start % core.block:][: 40 * core.block].reshape(40, -1) ** 2, axis=1))

    assert np.all(block_rms(closed) <= block_rms(alone) * 1.0001 + 1e-9)
    assert (core.stats.plate_closes, core.stats.press_ignored, core.stats.presses, core.stats.lifts) == (1, 1, 0, 0)
    assert core.instruments.instruments["hihat"].p.openness == 0.0


def test_plate_presses_on_anything_but_a_hihat_and_their_lifts_stay_ignored() -> None:
    stray = Damping(seq=0, time=0.2, instrument="snare", part="hihat_top", state=1, zone="centre", r=0.0, theta=0.0,
                    force=0.1)
    x, core = _render("modal", [_stroke(0, OPEN_AT_S, "open"), stray, _plates(1, 0.3, 0)], 0.5)
    assert (core.stats.plate_closes, core.stats.press_ignored) == (0, 2)
    assert core.instruments.instruments["hihat"].p.openness == 1.0


def _plate_contact(step: int, part: str, velocity: float) -> Contact:
    return Contact(time=step / 1000, step=step, instrument="hihat", part=part, x=0.0, y=0.0, z=0.8, local_x=0.0,
                   local_y=0.0, local_z=0.0, normal_x=0.0, normal_y=0.0, normal_z=1.0, normal_velocity=velocity,
                   impulse=1e-4, normal_force=0.06, openness=0.0)


@pytest.mark.parametrize("part", ["hihat_rattle", "hihat_top"])
def test_interaction_reports_plates_meeting_too_slowly_to_sound_as_a_press(part: str) -> None:
    """Physics reports resting plates for 10 ms (services.physics.contacts.PLATE_CONTACT_S), less than a press
    takes (press_after, 25 ms): the plates' touch is a press at once, ended with the report."""
    seg = Segmenter(load_kit("default", warn=False))
    events = []
    for step in range(2215, 2225):
        events += seg.contact(_plate_contact(step, part, 0.0), step / 1000)
    events += seg.contact(Contact(**{**_plate_contact(2300, "right_stick_tip", 3.0).model_dump(),
                                     "instrument": "snare"}), 2.3)  # time goes on: the plates' report is over
    presses = [e for e in events if isinstance(e, DampingChange)]
    assert [(e.part, e.state, e.instrument) for e in presses] == [(part, 1, "hihat"), (part, 0, "hihat")]
    assert presses[0].time == pytest.approx(2.215) and presses[1].time == pytest.approx(2.225)
    assert seg.stats.touches == 1 and seg.stats.dampings == 1
    assert not any(isinstance(e, ImpactOnset) and e.impact.instrument == "hihat" for e in events)


def test_a_stick_knocking_the_plates_together_is_still_a_rattle_and_a_chick_still_a_chick() -> None:
    seg = Segmenter(load_kit("default", warn=False))
    events = seg.contact(_plate_contact(1000, "hihat_rattle", 0.4), 1.0)
    events += seg.contact(_plate_contact(1500, "hihat_top", 0.5), 1.5)
    assert not any(isinstance(e, DampingChange) for e in events)
    assert seg.stats.rattles == 1
    assert [e.impact.part for e in events if isinstance(e, ImpactOnset)] == ["hihat_top"]


# ------------------------------------------------------------------------------------- every model chokes its voices

CLOSES = {
    "closed stroke": lambda t: [_stroke(1, t, "closed", "left_stick_tip")],
    "chick": lambda t: [_stroke(1, t, "closed", "hihat_top")],
    "plates": lambda t: [_plates(0, t, 1), _plates(1, t + 0.01, 0)],
}
WINDOWS = {  # model -> (close time, window measured: s, most of the open stroke's energy there left after it)
    "modal": (0.3, (0.4, 0.7), 0.03),  # 15 dB down at least
    "synth": (0.3, (0.4, 0.7), 0.03),
    # the open sample is 117 ms long: the window is its end, over which the choke's 77 ms fade is still under way
    # (unchoked the stroke leaves 1.0-1.15 of it there, with the close's own sound; choked 0.17-0.21)
    "sample": (0.12, (0.14, 0.215), 0.35),
}


@pytest.mark.parametrize("model", ["modal", "synth", "sample"])
@pytest.mark.parametrize("close", list(CLOSES))
def test_closing_the_hat_chokes_the_open_hat_in_every_model(model: str, close: str) -> None:
    """What is left of the open stroke (open then close, minus the close alone) is far below the open stroke
    alone."""
    close_s, (a, b), most = WINDOWS[model]
    opened, core = _render(model, [_stroke(0, OPEN_AT_S, "open")], b + 0.05)
    both, _ = _render(model, [_stroke(0, OPEN_AT_S, "open"), *CLOSES[close](close_s)], b + 0.05)
    alone, _ = _render(model, CLOSES[close](close_s), b + 0.05)
    sr = core.sample_rate
    left = _energy(both, sr, a, b) - _energy(alone, sr, a, b)
    assert _energy(opened, sr, a, b) > 0.0
    assert left < most * _energy(opened, sr, a, b)


def test_a_half_open_stroke_fades_the_open_voices_slower_than_a_closed_one() -> None:
    def left(zone: str) -> float:
        both, core = _render("synth", [_stroke(0, OPEN_AT_S, "open"), _stroke(1, 0.3, zone, "left_stick_tip")], 0.5)
        alone, _ = _render("synth", [_stroke(1, 0.3, zone, "left_stick_tip")], 0.5)
        return _energy(both, core.sample_rate, 0.32, 0.4) - _energy(alone, core.sample_rate, 0.32, 0.4)

    opened, core = _render("synth", [_stroke(0, OPEN_AT_S, "open")], 0.5)
    assert left("closed") < left("half") < _energy(opened, core.sample_rate, 0.32, 0.4)
