"""Presses damp the sound: a stick or hand resting on an instrument (/batteur/damping) shortens its ring."""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np
import pytest
from sound_helpers import SR, impact, one_drum_kit

from common.kit import Kit, load_kit
from common.messages import OscMessage
from common.messages.interaction import Damping
from common.messages.sound import SoundDamping, SoundModel
from services.sound.core import SoundCore, SoundSettings
from services.sound.instruments import Membrane
from services.sound.modal_bank import ModeSet
from services.sound.voices import NoiseVoice

LATENCY_S = 0.01
STRIKE_S = 0.1  # rig time of the strike, seconds
PRESS_S = 0.3  # rig time the stick comes to rest, seconds (heard LATENCY_S later)


def press(seq: int, t: float, state: int = 1, *, instrument: str = "drum", part: str = "left_stick_tip",
          force: float = 5.0, r: float = 0.5, theta: float = 0.0) -> Damping:
    return Damping(seq=seq, time=t, instrument=instrument, part=part, state=state, zone="centre", r=r,
                   theta=theta, force=force if state else 0.0)


def _core(kit: Kit | None = None, **settings: object) -> SoundCore:
    return SoundCore(SoundSettings(latency=LATENCY_S, use_pyo=False, **settings), kit or one_drum_kit())


def _render(messages: Sequence[OscMessage], until: float = 1.0, kit: Kit | None = None, source: str = "interaction",
            **settings: object) -> tuple[np.ndarray, SoundCore]:
    """Everything handled at rig time 0 (as an offline render does), rendered to ``until`` seconds."""
    core = _core(kit, **settings)
    try:
        for message in messages:
            core.handle(message, 0.0, source)
        core.render(until)
        return core.recording(), core
    finally:
        core.close()


def _rms(x: np.ndarray, t0: float, t1: float) -> float:
    return float(np.sqrt(np.mean(x[int(t0 * SR):int(t1 * SR)].astype(np.float64) ** 2)))


def _decay_db_per_s(x: np.ndarray, t0: float, t1: float) -> float:
    """Decay of the 10 ms RMS envelope between rig times t0 and t1, dB per second (a line fitted to it)."""
    times = np.arange(t0, t1, 0.01)
    levels = [20.0 * np.log10(_rms(x, t, t + 0.01)) for t in times]
    return float(-np.polyfit(times, levels, 1)[0])


STRUCK = impact(1, STRIKE_S)


def test_a_stick_resting_on_a_ringing_drum_damps_it_and_lifting_it_lets_it_ring_on() -> None:
    free, _ = _render([STRUCK])
    pressed, core = _render([STRUCK, press(1, PRESS_S)])
    lifted, _ = _render([STRUCK, press(1, PRESS_S), press(2, 0.5, 0)])
    heard = PRESS_S + LATENCY_S
    assert core.stats.presses == 1
    # 100 ms after the press the ring is far below the free one (5 N on a snare: T60 about 4x shorter)
    assert _rms(pressed, heard + 0.1, heard + 0.12) < 0.1 * _rms(free, heard + 0.1, heard + 0.12)
    assert _decay_db_per_s(pressed, heard + 0.01, heard + 0.1) > 3.0 * _decay_db_per_s(free, heard + 0.01,
                                                                                      heard + 0.1)
    free_rate = _decay_db_per_s(free, 0.6, 0.9)
    # lifted (heard at 0.51 s): quieter than the free ring (what the press took is gone), decaying at its rate
    assert _rms(lifted, 0.6, 0.62) < 0.2 * _rms(free, 0.6, 0.62)
    assert _decay_db_per_s(lifted, 0.6, 0.9) == pytest.approx(free_rate, rel=0.15)


def test_the_drum_decays_at_its_own_rate_again_once_lifted() -> None:
    core = _core()
    try:
        drum = core.instruments.instruments["drum"]
        own = drum.bank.decay.copy()
        for message in (STRUCK, press(1, PRESS_S), press(2, 0.5, 0)):
            core.handle(message, 0.0, "interaction")
        core.render(0.4)
        assert np.all(drum.bank.decay >= own) and np.any(drum.bank.decay > 2.0 * own)
        core.render(0.6)
        assert np.array_equal(drum.bank.decay, own)
        assert core.stats.lifts == 1
    finally:
        core.close()


def test_a_press_takes_effect_on_its_sample() -> None:
    free, _ = _render([STRUCK], until=0.5)
    pressed, _ = _render([STRUCK, press(1, PRESS_S)], until=0.5)
    sample = round((PRESS_S + LATENCY_S) * SR)
    assert sample % 256 != 0  # inside a block, not on its edge
    differ = np.nonzero(free != pressed)[0]
    assert differ.size and sample <= differ[0] <= sample + 1


def test_a_hand_chokes_a_crash_in_a_tenth_to_three_tenths_of_a_second() -> None:
    kit = load_kit("default")
    crash = impact(1, STRIKE_S, "crash", velocity=4.0, r=0.8)
    choke = press(1, PRESS_S, instrument="crash", part="left_hand", force=10.0, r=0.95)
    free, _ = _render([crash], until=1.2, kit=kit)
    choked, _ = _render([crash, choke], until=1.2, kit=kit)
    heard = PRESS_S + LATENCY_S
    t60_s = 60.0 / _decay_db_per_s(choked, heard + 0.01, heard + 0.15)
    assert 0.1 <= t60_s <= 0.3
    assert 60.0 / _decay_db_per_s(free, heard + 0.01, heard + 0.15) > 3.0  # the same crash rings seconds
    # a stick tip resting there with the same force damps much less than the hand
    tip, _ = _render([crash, press(1, PRESS_S, instrument="crash", force=10.0, r=0.95)], until=1.2, kit=kit)
    assert 60.0 / _decay_db_per_s(tip, heard + 0.01, heard + 0.15) > 3.0 * t60_s


def test_redundant_copies_of_a_press_apply_once() -> None:
    once, _ = _render([STRUCK, press(1, PRESS_S), press(2, 0.5, 0)])
    copies = [STRUCK] + [press(1, PRESS_S)] * 5 + [press(2, 0.5, 0)] * 5
    again, core = _render(copies)
    assert np.array_equal(once, again)
    assert (core.stats.presses, core.stats.lifts, core.stats.duplicates) == (1, 1, 8)


def test_press_and_impact_numbers_are_separate() -> None:
    """An impact and a press with the same seq from the same sender are both heard (each has its own numbers)."""
    _, core = _render([impact(7, STRIKE_S), press(7, PRESS_S)])
    assert (core.stats.strikes, core.stats.presses, core.stats.duplicates) == (1, 1, 0)


def test_a_lift_without_its_press_is_counted_and_ignored() -> None:
    free, _ = _render([STRUCK])
    stray, core = _render([STRUCK, press(5, PRESS_S, 0)])
    assert np.array_equal(free, stray)
    assert (core.stats.stray_lifts, core.stats.lifts, core.rejected_total) == (1, 0, 0)


def test_presses_on_unknown_instruments_or_with_impossible_forces_are_counted_and_dropped() -> None:
    """(A non-finite force never gets here: decoding drops it.)"""
    free, _ = _render([STRUCK])
    messages = [STRUCK, press(1, PRESS_S, instrument="gong"), press(2, PRESS_S, force=1e30),
                press(3, PRESS_S, force=1e9)]
    dropped, core = _render(messages)
    assert np.array_equal(free, dropped)
    assert (core.stats.press_unknown, core.stats.press_malformed) == (1, 2)
    assert core.rejected_total == 3  # Health's dropped


def test_presses_on_pedals_and_the_closed_hihat_plates_are_not_applied_twice() -> None:
    """The plates pressed together are the hat's openness (0: what a closed stroke plays already), not a damper on
    top of it (an open hat's plates closing: tests/sound/test_sound_hihat_close.py)."""
    kit = load_kit("default")
    hat = impact(1, STRIKE_S, "hihat", zone="closed")
    free, _ = _render([hat], until=0.6, kit=kit)
    held, core = _render([hat, press(1, PRESS_S, instrument="hihat_pedal", part="left_foot_ball"),
                          press(2, PRESS_S, instrument="hihat", part="hihat_top")], until=0.6, kit=kit)
    assert np.array_equal(free, held)
    assert (core.stats.press_ignored, core.stats.plate_closes, core.stats.presses) == (1, 1, 0)
    assert core.rejected_total == 0


def test_two_parts_resting_at_once_add_and_each_lifts_its_own() -> None:
    def decay_after(messages: list[Damping], until: float) -> np.ndarray:
        core = _core()
        try:
            for message in [STRUCK, *messages]:
                core.handle(message, 0.0, "interaction")
            core.render(until)
            return core.instruments.instruments["drum"].bank.decay.copy()
        finally:
            core.close()

    left = press(1, PRESS_S, part="left_stick_tip", r=0.3)
    right = press(2, PRESS_S, part="right_hand", force=3.0, r=0.6, theta=1.0)
    one, both = decay_after([right], 0.4), decay_after([left, right], 0.4)
    assert np.all(both >= one) and np.any(both > one)
    assert np.array_equal(decay_after([left, right, press(3, 0.45, 0, part="left_stick_tip")], 0.5), one)


def test_a_press_holds_through_a_damping_change_in_the_background() -> None:
    """The live node rebuilds on a worker: the press must still damp the adopted modes, and lifting it gives the
    new damping law alone (the same tables as an offline core with that law)."""
    change = SoundDamping(instrument="drum", sigma0=8.0, sigma1=1e-5)
    core = _core(background_rebuilds=True, record=False)
    reference = _core()
    try:
        drum = core.instruments.instruments["drum"]
        core.handle(press(1, 0.0), 0.0, "interaction")
        core.step(0.05)
        core.handle(change, core.now, "panel")
        deadline = time.monotonic() + 120.0
        while core.rebuilding:
            assert time.monotonic() < deadline, "the background change never finished"
            core.step(core.now + 0.001)
            time.sleep(0.002)
        reference.handle(change, 0.0, "panel")
        law = reference.instruments.instruments["drum"].bank.decay
        assert drum.p.damping0 == 8.0
        assert np.all(drum.bank.decay >= law) and np.any(drum.bank.decay > 2.0 * law)
        core.handle(press(2, core.now - LATENCY_S + 0.001, 0), core.now, "interaction")
        core.step(core.now + 0.02)
        assert np.array_equal(drum.bank.decay, law)
    finally:
        core.close()
        reference.close()


@pytest.mark.parametrize("model", ["sample", "synth"])
def test_presses_damp_the_sample_and_synth_models_too(model: str) -> None:
    kit = load_kit("default")
    snare = impact(1, STRIKE_S, "snare", velocity=4.0)
    set_model = SoundModel(instrument="snare", model=model)
    free, _ = _render([set_model, snare], until=0.6, kit=kit)
    pressed, core = _render([set_model, snare, press(1, 0.15, instrument="snare")], until=0.6, kit=kit)
    assert core.stats.presses == 1
    assert _rms(pressed, 0.26, 0.3) < 0.1 * _rms(free, 0.26, 0.3)


def test_a_press_on_a_snare_shortens_its_ringing_wires() -> None:
    kit = load_kit("default")
    core = _core(kit)
    try:
        core.handle(impact(1, STRIKE_S, "snare"), 0.0, "interaction")
        core.handle(press(1, PRESS_S, instrument="snare"), 0.0, "interaction")
        core.render(0.2)
        snare = core.instruments.instruments["snare"]
        assert isinstance(snare, Membrane)
        wires = [v for v in core.pool.voices if isinstance(v, NoiseVoice) and v.press_exempt]
        assert wires and wires[0].decay == pytest.approx(snare.wire_decay())
        free_decay = wires[0].decay
        core.render(0.4)
        assert wires[0].decay < free_decay / 3.0
    finally:
        core.close()


def test_a_late_press_applies_at_once_and_is_counted_late() -> None:
    core = _core()
    try:
        core.handle(STRUCK, 0.0, "interaction")
        core.render(0.5)
        core.handle(press(1, PRESS_S), core.now, "interaction")  # its sample was rendered 190 ms ago
        core.render(0.6)
        assert core.late == 1 and core.stats.presses == 1
        assert core.instruments.instruments["drum"].presses
    finally:
        core.close()


def test_the_bank_changes_its_decay_on_the_sample_and_keeps_strikes_after_it() -> None:
    """One mode struck at sample 10, decaying at 20 1/s, then 400 1/s from sample 100, struck again at 180:
    the rendered block is the closed form to float32 precision."""
    f, slow, fast = 440.0, 20.0, 400.0
    bank = ModeSet(SR, 256)
    bank.set_modes([f], [slow])
    bank.strike([1.0 + 0.0j], 10)
    bank.retune([fast], 100)
    bank.strike([0.5j], 180)
    out = np.zeros(256, dtype=np.float32)
    bank.process(out)
    n = np.arange(256)
    p_slow, p_fast = np.exp((-slow + 2j * np.pi * f) / SR), np.exp((-fast + 2j * np.pi * f) / SR)
    first = np.where(n < 100, p_slow ** (n - 10.0), p_slow**90 * p_fast ** (n - 100.0)) * (n >= 10)
    second = 0.5j * p_fast ** (n - 180.0) * (n >= 180)
    assert np.allclose(out, np.imag(first + second), atol=1e-6)
    out[:] = 0.0
    bank.process(out)  # the next block goes on at the fast rate
    n2 = n + 256
    expected = np.imag(p_slow**90 * p_fast ** (n2 - 100.0) + 0.5j * p_fast ** (n2 - 180.0))
    assert np.allclose(out, expected, atol=1e-6)


def test_a_drum_struck_while_a_stick_rests_on_it_rings_short() -> None:
    """The press lands on a silent drum (applied at once) and the strike that follows is damped."""
    free, _ = _render([STRUCK], until=0.5)
    resting, core = _render([press(1, 0.05), STRUCK], until=0.5)
    heard = STRIKE_S + LATENCY_S
    assert core.stats.presses == 1
    assert _rms(resting, heard + 0.1, heard + 0.12) < 0.1 * _rms(free, heard + 0.1, heard + 0.12)


def test_a_part_that_strikes_again_has_left_what_it_rested_on() -> None:
    """Its lift lost (or in another render segment): the stick's next strike, here on another drum, lifts it, so
    the drum is not damped for good; the late lift is then a stray one."""
    kit = load_kit("default")
    snare, tom = impact(1, STRIKE_S, "snare"), impact(2, 0.5, "hightom")  # both by the right stick tip
    resting = press(1, PRESS_S, instrument="snare", part=snare.part)
    core = _core(kit)
    try:
        for message in (snare, resting, tom, press(2, 0.6, 0, instrument="snare", part=snare.part)):
            core.handle(message, 0.0, "interaction")
        own = core.instruments.instruments["snare"].bank.decay.copy()
        core.render(0.45)
        assert np.any(core.instruments.instruments["snare"].bank.decay > 2.0 * own)
        core.render(0.7)
        assert np.array_equal(core.instruments.instruments["snare"].bank.decay, own)
        assert (core.stats.implicit_lifts, core.stats.lifts, core.stats.stray_lifts) == (1, 0, 1)
    finally:
        core.close()


def test_random_presses_and_lifts_never_break_the_render() -> None:
    """Any mix of presses, lifts, forces, positions, parts and instruments (known or not) among strikes: the
    render stays finite and nothing rests once everything is lifted."""
    kit = load_kit("default")
    rng = np.random.default_rng(11)
    names = [o.id for o in kit.objects] + ["gong"]
    parts = ["left_stick_tip", "right_stick_shaft", "left_hand", "kick_beater", "hihat_top"]
    messages: list[OscMessage] = [impact(i, float(t), str(rng.choice(names[:10])), velocity=float(rng.uniform(0.5, 8)))
                                  for i, t in enumerate(rng.uniform(0.0, 1.8, 60))]
    messages += [press(i, float(t), int(rng.integers(0, 2)), instrument=str(rng.choice(names)),
                       part=str(rng.choice(parts)), force=float(rng.choice([0.0, 1e-3, 5.0, 300.0, 4999.0])),
                       r=float(rng.uniform(0, 2)), theta=float(rng.uniform(-7, 7)))
                 for i, t in enumerate(rng.uniform(0.0, 1.8, 300))]
    messages += [press(1000 + i, 1.9, 0, instrument=name, part=part) for i, (name, part) in
                 enumerate((n, p) for n in names for p in parts)]
    audio, core = _render(messages, until=2.5, kit=kit)
    assert np.isfinite(audio).all() and np.abs(audio).max() > 0.0
    assert core.stats.presses > 50 and core.stats.press_unknown > 0
    assert not any(inst.presses for inst in core.instruments.instruments.values())
    assert not core.pool.press_rates
