"""Floods of impacts: the node keeps playing, memory stays bounded, every impact not played is counted and told."""

from __future__ import annotations

import argparse
import logging

import pytest
from sound_helpers import impact, one_drum_kit

from common.config import load_settings
from services.sound.core import SoundCore, SoundSettings
from services.sound.node import MAX_PENDING, make_core


def _node_core() -> SoundCore:
    settings = load_settings({"role": "sound", "discovery": False, "clock_master": "self", "latency_s": 0.05})
    extra = argparse.Namespace(kit="default", wav=None, device="none", model="modal", block_size=256, channels=1,
                               reverb=0.0)
    return make_core(settings, extra)


def test_a_burst_of_thousands_of_strikes_plays_the_loudest_and_counts_the_rest() -> None:
    core = SoundCore(SoundSettings(latency=0.0, use_pyo=False, record=False), one_drum_kit())
    for seq in range(2000):  # all due in the same block
        core.handle(impact(seq, 0.001, velocity=1.0 + (seq == 1234) * 5.0), 0.0, "flood")
    core.render(0.5)
    # was: every one of the 2000 strikes computed in one block, the renderer stalled for seconds
    cap = core.settings.max_strikes_per_block
    assert core.stats.strikes == cap and core.stats.overload == 2000 - cap
    assert max(core.strike_latencies) < 0.01 and len(core.scheduler) == 0
    assert core.stats.rejected_total == 2000 - cap  # what the node's Health reports as dropped
    core.close()


def test_the_loudest_strike_of_a_burst_is_among_those_played() -> None:
    core = SoundCore(SoundSettings(latency=0.0, use_pyo=False, record=False, max_strikes_per_block=1), one_drum_kit())
    core.handle(impact(1, 0.001, velocity=0.5), 0.0, "t")
    core.handle(impact(2, 0.002, velocity=6.0), 0.0, "t")
    played: list[float] = []
    inst = core.instruments.instruments["drum"]
    real = inst.strike
    inst.strike = lambda strike, pool: (played.append(strike.velocity), real(strike, pool))  # type: ignore[method-assign]
    core.render(0.1)
    assert played == [6.0] and core.stats.overload == 1
    core.close()


def test_the_node_drops_impacts_far_ahead_of_its_clock() -> None:
    core = _node_core()
    try:
        core.step(100.0)
        for seq in range(1000):  # a sender whose clock is hours ahead
            core.handle(impact(seq, 100.0 + 3600.0 + seq, "snare"), 100.0, "wrong-clock")
        # was: every one held in memory until its time came, an hour later
        assert len(core.scheduler) == 0 and core.stats.too_early == 1000 and core.stats.rejected_total == 1000
        core.handle(impact(5000, 100.01, "snare"), 100.0, "good")  # an impact on time still plays
        core.step(100.2)
        assert core.stats.strikes == 1
    finally:
        core.close()


def test_the_node_holds_a_bounded_number_of_impacts() -> None:
    core = _node_core()
    try:
        core.step(0.0)
        for seq in range(MAX_PENDING + 500):  # a flood, all due within the horizon
            core.handle(impact(seq, 5.0, "snare"), 0.0, "flood")
        assert len(core.scheduler) == MAX_PENDING and core.stats.overload == 500
    finally:
        core.close()


def test_impacts_on_an_unknown_instrument_are_told_once_and_counted(caplog: pytest.LogCaptureFixture) -> None:
    core = SoundCore(SoundSettings(latency=0.0, use_pyo=False, record=False))
    with caplog.at_level(logging.WARNING, logger="batteur.sound"):
        for seq in range(100):
            core.handle(impact(seq, 0.0, "snaer"), 0.0, "panel")
    # was: silence, counted only in core.stats (not in Health, not in the log)
    warnings = [r.getMessage() for r in caplog.records]
    assert len(warnings) == 1 and "'snaer', which the kit does not have (known: china, cowbell, crash" in warnings[0]
    assert core.stats.unknown_instrument == 100 and core.stats.rejected_total == 100
    assert core.rejected_total == 100  # read by the node's Health (dropped)
    with caplog.at_level(logging.WARNING, logger="batteur.sound"):
        core.render(1.5)  # a second later the next one is told again, with the count of those not told
        core.handle(impact(100, core.now, "snaer"), core.now, "panel")
    assert len(caplog.records) == 2 and "(+99 more since the last report)" in caplog.records[1].getMessage()
    core.close()
