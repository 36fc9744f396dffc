"""Sound controls as docs/sound.md and docs/osc.md describe them: a hi-hat strike's zone open/half/closed sets
the openness from that strike on, as /batteur/sound/openness does; /batteur/sound/position 0 ignores the strike
point."""

from __future__ import annotations

import numpy as np
import pytest
from sound_helpers import impact

from common.messages.sound import SoundOpenness, SoundPosition
from services.sound.core import SoundCore, SoundSettings


def _bow_ring(first_zone: str, control: float | None = None) -> tuple[float, float]:
    """(openness when the second strike lands, its level 0.25-0.3 s later): a strike in ``first_zone``, then,
    after an optional /batteur/sound/openness, a bow strike (a zone that says nothing about the pedal)."""
    core = SoundCore(SoundSettings(latency=0.0, use_pyo=False))
    try:
        core.handle(impact(1, 0.0, "hihat", zone=first_zone, velocity=4.0, r=0.7), 0.0, "t")
        core.render(1.0)  # the first strike has died away (or been choked)
        if control is not None:
            core.handle(SoundOpenness(instrument="hihat", value=control), core.now, "panel")
        core.handle(impact(2, 1.0, "hihat", zone="bow", velocity=4.0, r=0.7), core.now, "t")
        core.render(1.25)
        openness = core.instruments.instruments["hihat"].p.openness
        return openness, float(np.max(np.abs(core.render(1.3))))
    finally:
        core.close()


def test_a_hihat_zone_sets_the_openness_for_the_strikes_that_follow() -> None:
    open_then_bow = _bow_ring("open")
    closed_then_bow = _bow_ring("closed")
    assert open_then_bow[0] == 1.0 and closed_then_bow[0] == 0.0
    assert closed_then_bow[1] < 0.1 * open_then_bow[1]  # the bow strike rings open only after an open one
    reopened = _bow_ring("closed", control=1.0)  # the control overrides what the zone set
    assert reopened[0] == 1.0 and reopened[1] > 0.5 * open_then_bow[1]


def _strike_at(instrument: str, r: float, theta: float, position: float) -> np.ndarray:
    core = SoundCore(SoundSettings(latency=0.0, use_pyo=False))
    try:
        core.handle(SoundPosition(instrument=instrument, value=position), 0.0, "panel")
        core.handle(impact(1, 0.0, instrument, r=r, theta=theta, zone="centre"), 0.0, "t")
        return core.render(0.3)
    finally:
        core.close()


@pytest.mark.parametrize("instrument", ["snare", "kick", "crash", "ride", "hihat"])
def test_position_0_ignores_the_strike_point(instrument: str) -> None:
    """/batteur/sound/position 0 is "position ignored" (docs/osc.md): two strikes at different radii and angles
    (both on the bow of a cymbal) sound the same; at the default 1 they differ; in between, in between."""
    here, there = (0.55, 0.1), (0.8, 2.0)
    same = [_strike_at(instrument, *point, position=0.0) for point in (here, there)]
    np.testing.assert_allclose(same[0], same[1], rtol=0, atol=1e-6 * float(np.max(np.abs(same[0]))))
    full = [_strike_at(instrument, *point, position=1.0) for point in (here, there)]
    half = [_strike_at(instrument, *point, position=0.5) for point in (here, there)]
    full_diff, half_diff = (float(np.max(np.abs(a - b))) for a, b in (full, half))
    assert 0.0 < half_diff < full_diff and full_diff > 0.1 * float(np.max(np.abs(full[0])))


def test_a_latency_under_three_blocks_sent_live_is_warned_about(caplog: pytest.LogCaptureFixture) -> None:
    """As the node warns for --latency-s at start: under three blocks (16 ms at 256 samples) most strikes are late."""
    from common.messages.sound import SoundLatency

    core = SoundCore(SoundSettings(latency=0.05, use_pyo=False))
    with caplog.at_level("WARNING", logger="batteur.sound"):
        core.handle(SoundLatency(value=0.05), 0.0, "panel")
        assert not caplog.records
        core.handle(SoundLatency(value=0.01), 0.0, "panel")
    assert core.scheduler.latency == pytest.approx(0.01)  # applied: the user may know better
    assert "under three blocks" in caplog.text and "panel" in caplog.text
