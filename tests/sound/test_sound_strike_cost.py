"""A strike on an instrument with very many modes does no per-mode special-function work in the render loop, and
what it plays is what the exact formulas give; the default kit's strikes are computed exactly as before."""

from __future__ import annotations

from dataclasses import fields

import numpy as np
import numpy.typing as npt
import pytest
from scipy import signal
from scipy.special import jv
from sound_helpers import impact, one_drum_kit

from common.messages.sound import SoundModel, SoundModes
from services.sound import membrane
from services.sound.core import SoundCore, SoundSettings
from services.sound.excitation import Striker, hunt_crossley, mode_response_chunks
from services.sound.membrane import SHAPE_TABLE_MODES, circular_mode_shapes, membrane_modes
from services.sound.modal_bank import BankTables, ModeSet
from services.sound.plates import plate_modes


def _exact(modes: membrane.MembraneModes, r: float, theta: float) -> npt.NDArray[np.float64]:
    return circular_mode_shapes(modes.m, modes.orientation, modes.zeros, r, theta)


def test_the_shapes_of_a_20000_mode_drum_are_the_bessel_functions() -> None:
    modes = membrane_modes(0.178, 3700.0, 0.35, 20000, 1.0, 0.002)
    for r in np.linspace(0.0, 1.0, 23):
        assert np.max(np.abs(modes.shape_at(r, 0.7) - _exact(modes, r, 0.7))) < 1e-8
    centre = modes.shape_at(0.0, 0.7)
    assert np.all(centre[modes.m > 0] == 0.0) and np.all(centre[modes.m == 0] == 1.0)  # only m = 0 at the centre
    plate = plate_modes(0.59, 0.00031, 20000)
    assert plate.m.shape[0] == 20000
    exact = circular_mode_shapes(plate.m, plate.orientation, plate.k_a, 0.6, 1.1)
    assert np.max(np.abs(plate.shape_at(0.6, 1.1) - exact)) < 1e-8


def test_a_strike_on_a_20000_mode_drum_calls_no_bessel_function_per_mode(monkeypatch: pytest.MonkeyPatch) -> None:
    core = SoundCore(SoundSettings(latency=0.0, use_pyo=False), one_drum_kit())
    try:
        core.handle(SoundModes(instrument="drum", value=20000), 0.0, "panel")  # offline: built here, at once
        largest: list[int] = []

        def counting_jv(order: npt.ArrayLike, x: npt.ArrayLike) -> object:
            largest.append(int(np.size(x)))
            return jv(order, x)

        monkeypatch.setattr(membrane, "jv", counting_jv)
        for seq, r in enumerate((0.05, 0.4, 0.93)):
            core.handle(impact(seq, core.now + 0.001, r=r), core.now, "t")
            core.render(core.now + 0.02)
        # was: the loop evaluated J_m at all 20,000 modes per strike (about 95 ms)
        assert core.stats.strikes == 3 and max(largest, default=0) < 100
        assert np.max(np.abs(core.recording())) > 0.01
    finally:
        core.close()


def test_the_default_kit_computes_every_shape_exactly() -> None:
    core = SoundCore(SoundSettings(use_pyo=False, record=False))
    try:
        for inst in core.instruments.instruments.values():
            for modes in (getattr(inst, "modes", None), getattr(inst, "reso", None)):
                if modes is not None:
                    assert modes.m.shape[0] <= SHAPE_TABLE_MODES and modes.radial is None, inst.id
    finally:
        core.close()


def test_shapes_read_from_the_grid_do_not_depend_on_what_was_computed_before(
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(membrane, "_GRIDS", [])
    small = membrane_modes(0.178, 3700.0, 0.35, 3000).shape_at(0.41, 0.2)
    membrane_modes(0.3, 3700.0, 0.35, 20000)  # a larger grid replaces the first
    assert np.array_equal(membrane_modes(0.178, 3700.0, 0.35, 3000).shape_at(0.41, 0.2), small)


def test_the_bank_s_inverse_powers_inject_the_same_amplitudes_as_computing_them_per_chunk() -> None:
    bank = ModeSet(48000, 256)
    rng = np.random.default_rng(3)
    freq = rng.uniform(40.0, 20000.0, 500)
    bank.set_modes(freq, 3.0 + 1e-5 * freq**2)
    for velocity, stiffness in ((0.5, 2e5), (3.0, 6e6), (12.0, 1e9)):
        pulse = hunt_crossley(velocity, Striker(0.03, stiffness, 1.5), 0.6, 48000.0, oversample=8)
        f = pulse.force
        idx = np.nonzero(f)[0]
        expected = []  # the formula as it was: an exponential per mode and sample of every chunk
        for start in range(int(idx[0]), int(idx[-1]) + 1, 8):
            m = np.arange(start, min(start + 8, int(idx[-1]) + 1))
            expected.append((start, np.exp(-np.outer(bank.poles_log, m - start)) @ (f[m] / pulse.sample_rate)))
        got = mode_response_chunks(pulse, bank.poles_log, inverse_powers=bank.tables.inverse_powers)
        assert [s for s, _ in got] == [s for s, _ in expected]
        assert all(np.array_equal(a, b) for (_, a), (_, b) in zip(got, expected, strict=True))  # bit for bit


def test_a_bank_adopting_another_takes_every_table_and_keeps_its_ringing() -> None:
    rng = np.random.default_rng(5)
    old_f = rng.uniform(50.0, 5000.0, 40)
    new_f = np.sort(rng.uniform(50.0, 9000.0, 60))
    ringing, fresh = ModeSet(48000, 256), ModeSet(48000, 256)
    for bank in (ringing, fresh):
        bank.set_modes(old_f, np.full(40, 4.0))
        bank.strike(np.ones(40) * 1e-3, 17)
        bank.process(np.zeros(256, dtype=np.float32))
    built = ModeSet(48000, 256)
    built.set_modes(new_f, 2.0 + 1e-6 * new_f**2)  # elsewhere (the worker)
    ringing.adopt(built)
    fresh.set_modes(new_f, 2.0 + 1e-6 * new_f**2)
    for f in fields(BankTables):
        assert np.array_equal(getattr(ringing.tables, f.name), getattr(fresh.tables, f.name)), f.name
    out = [np.zeros(256, dtype=np.float32) for _ in range(2)]
    for bank, buf in zip((ringing, fresh), out, strict=True):
        bank.strike(np.ones(60) * 1e-3, 5)
        for _ in range(4):
            bank.process(buf)
    assert np.array_equal(out[0], out[1]) and np.any(out[0] != 0)


def test_repeated_strikes_design_no_new_filters(monkeypatch: pytest.MonkeyPatch) -> None:
    core = SoundCore(SoundSettings(latency=0.0, use_pyo=False))
    try:
        for model in ("modal", "synth"):
            core.handle(SoundModel(instrument="snare", model=model), core.now, "panel")
            core.handle(impact(1 if model == "modal" else 3, core.now + 0.001, "snare"), core.now, "t")
            core.render(core.now + 0.02)
        designed: list[object] = []
        butter = signal.butter

        def counting_butter(*args: object, **kwargs: object) -> object:
            designed.append(args)
            return butter(*args, **kwargs)  # type: ignore[arg-type]

        monkeypatch.setattr(signal, "butter", counting_butter)
        for seq, model in ((2, "modal"), (4, "synth")):
            core.handle(SoundModel(instrument="snare", model=model), core.now, "panel")
            core.handle(impact(seq, core.now + 0.001, "snare"), core.now, "t")
            core.render(core.now + 0.02)
        # was: every strike designed its noise voices' band-pass filters again (0.3 ms each, in the render loop)
        assert core.stats.strikes == 4 and designed == []
    finally:
        core.close()
