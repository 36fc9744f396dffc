"""A pedal controller (or the Pd panel's slider) streaming /batteur/sound/openness on a live sound node.

* A burst of openness messages within one block costs the render thread one retune of the hat's modes, at the
  latest value, applied before the block's strikes (before: every message rebuilt the hat's 506 modes at once,
  4.9 ms each against a 5.3 ms block).
* A retune changes the damping alone: the hat's modes decay exactly as a hat built at that openness.
* A hi-hat radius change computed in the background lands while the pedal keeps moving (before: each finished
  rebuild saw the openness changed and was redone, so it never landed while the messages came).
* A message the node has not rendered yet when it stops is in what --sound-params-out writes.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import replace

import numpy as np
import pytest

from common.kit import load_kit
from common.messages.sound import SoundOpenness, SoundRadius
from services.sound.core import SoundCore, SoundSettings
from services.sound.instruments import HiHat

KIT = load_kit("default", warn=False)


def _core(background_rebuilds: bool) -> SoundCore:
    return SoundCore(SoundSettings(latency=0.0, model="modal", use_pyo=False, record=False,
                                   background_rebuilds=background_rebuilds), KIT)


def _one_block(core: SoundCore) -> None:
    core.step(core.now + core.block / core.sample_rate)


def _wait(cond: Callable[[], object], what: str, timeout_s: float = 60.0) -> None:
    """Poll ``cond()`` until true (a generous deadline against a hang, not a timing assertion)."""
    deadline = time.monotonic() + timeout_s
    while not cond():
        assert time.monotonic() < deadline, what
        time.sleep(0.01)


def _count_retunes(monkeypatch: pytest.MonkeyPatch) -> list[float]:
    """Every change of a hi-hat's modal tables (a rebuild or a damping retune), as the openness it was made at."""
    calls: list[float] = []
    rebuild, retune = HiHat.rebuild, HiHat.retune_openness

    def counted_rebuild(self: HiHat) -> None:
        calls.append(self.p.openness)
        rebuild(self)

    def counted_retune(self: HiHat, openness: float, derived: bool = False) -> None:
        calls.append(openness)
        retune(self, openness, derived)

    monkeypatch.setattr(HiHat, "rebuild", counted_rebuild)
    monkeypatch.setattr(HiHat, "retune_openness", counted_retune)
    return calls


def test_a_burst_of_openness_messages_in_one_block_costs_one_retune(monkeypatch: pytest.MonkeyPatch) -> None:
    core = _core(background_rebuilds=True)
    try:
        _one_block(core)
        hat = core.instruments.instruments["hihat"]
        calls = _count_retunes(monkeypatch)
        for value in np.linspace(0.9, 0.2, 12):  # a slider dragged within one block
            assert core.handle(SoundOpenness(instrument="hihat", value=float(value)), core.now, "panel") == []
        _one_block(core)
        assert calls == [pytest.approx(0.2)]
        assert hat.p.openness == pytest.approx(0.2)
        _one_block(core)  # nothing new: nothing to do
        assert len(calls) == 1
    finally:
        core.close()


@pytest.mark.parametrize("openness", [0.0, 0.37, 1.0])
def test_a_retuned_hat_decays_as_one_built_at_its_openness(openness: float) -> None:
    core = _core(background_rebuilds=False)
    try:
        core.handle(SoundOpenness(instrument="hihat", value=openness), 0.0, "panel")
        _one_block(core)
        hat = core.instruments.instruments["hihat"]
        fresh = _core(background_rebuilds=False)
        try:
            built = fresh.instruments.instruments["hihat"]
            built.p = replace(built.p, openness=openness)
            built.rebuild()
            assert np.array_equal(hat.bank.freq, built.bank.freq)
            np.testing.assert_allclose(hat.bank.decay, built.bank.decay, rtol=1e-12)
            np.testing.assert_allclose(hat.bank.poles_log, built.bank.poles_log, rtol=1e-9)
        finally:
            fresh.close()
    finally:
        core.close()


def test_a_radius_change_lands_while_the_pedal_streams_openness() -> None:
    core = _core(background_rebuilds=True)
    try:
        _one_block(core)
        hat = core.instruments.instruments["hihat"]
        r0 = hat.p.radius
        core.handle(SoundRadius(instrument="hihat", value=round(r0 * 1.3, 4)), core.now, "panel")
        landed_at = None
        for i in range(20):  # a pedal moving: an openness each block, the rebuild finishing between two of them
            value = 0.2 + 0.03 * i
            core.handle(SoundOpenness(instrument="hihat", value=value), core.now, "pedal")
            _one_block(core)
            if hat.p.radius != r0:
                landed_at = i
                break
            _wait(lambda: all(job.future.done() for job in core._rebuilds.values()), "the rebuild never finished")
        assert landed_at is not None, "the radius change never landed while the pedal moved"
        assert hat.p.radius == pytest.approx(r0 * 1.3, abs=1e-4)
        assert hat.p.openness == pytest.approx(value)  # the pedal's latest, not the one the rebuild started at
        assert not core.rebuilding
        # the adopted modes are those of the new radius, damped at the pedal's openness
        fresh = _core(background_rebuilds=False)
        try:
            built = fresh.instruments.instruments["hihat"]
            built.p = replace(built.p, radius=hat.p.radius, openness=hat.p.openness)
            built.rebuild()
            assert np.array_equal(hat.bank.freq, built.bank.freq)
            np.testing.assert_allclose(hat.bank.decay, built.bank.decay, rtol=1e-12)
        finally:
            fresh.close()
    finally:
        core.close()


def test_the_pedals_last_openness_is_kept_when_the_node_stops_before_the_next_block() -> None:
    """--sound-params-out is written as the core closes (before_close): a message not rendered yet is in it."""
    core = _core(background_rebuilds=True)
    seen: list[float] = []
    hat = core.instruments.instruments["hihat"]
    core.before_close = lambda: seen.append(hat.p.openness)
    core.handle(SoundOpenness(instrument="hihat", value=0.85), 0.0, "pedal")
    core.close()
    assert seen == [0.85]
