"""Rig time that steps under a running sound core (the clock master restarted: rig time starts again from the new
master's launch): strikes of the new timeline are heard within the latency, the output neither stops nor bursts,
and a recording's sidecar says which rig time each stretch of the take holds.

Was: a backward step of 35 s left the node rendering nothing until the new rig time reached what it had already
played (35 s of silence, every strike meanwhile `late` and played in a heap); a forward step rendered the
skipped stretch at once; the sidecar gave the origin of the last timeline for the whole take."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pytest
from sound_helpers import impact, one_drum_kit

from common.config import load_settings
from services.sound.core import SoundCore, SoundSettings
from services.sound.node import make_core

SR = 48000
BLOCK = 256
LATENCY_S = 0.05
AHEAD_S = 2 * BLOCK / SR + 0.002  # as the node renders ahead
ONSET = 1e-4


def _live_core(record: bool = True) -> SoundCore:
    return SoundCore(SoundSettings(latency=LATENCY_S, origin=None, render_ahead=AHEAD_S, record=record, channels=1,
                                   block_size=BLOCK), one_drum_kit())


def _run(core: SoundCore, start: float, seconds: float) -> float:
    """Step the core as the node does (every block period) from rig time ``start``; returns the rig time reached."""
    n = int(round(seconds * SR / BLOCK))
    for k in range(n + 1):
        core.step(start + k * BLOCK / SR)
    return start + n * BLOCK / SR


def _stepped(core: SoundCore, step_s: float, now: float) -> None:
    """What the node does when its rig clock steps (a core without the hook is left to guess)."""
    hook = getattr(core, "clock_stepped", None)
    if hook is not None:
        hook(step_s, now)


@pytest.mark.parametrize("step_s", [-35.0, 3600.0])
def test_a_strike_after_the_clock_stepped_is_heard_within_the_latency(step_s: float) -> None:
    core = _live_core()
    try:
        old = _run(core, 54.0, 1.0)
        rendered = core.next_sample
        new = old + step_s
        _stepped(core, step_s, new)
        t = new + 0.2
        after = _run(core, new, 0.2 - 0.003)  # the impact arrives a few ms before its time, as a live one does
        # a step forward renders no burst: what it renders follows the wall clock, as before the step
        assert core.next_sample - rendered <= round(0.2 * SR) + 2 * BLOCK
        core.handle(impact(0, t), after, "interaction")
        _run(core, after, LATENCY_S + 0.05)
        assert core.late == 0 and core.stats.strikes == 1
        assert core.strike_latencies[-1] == pytest.approx(LATENCY_S, abs=1.0 / SR)
        audio = core.recording()
        due = rendered + round((t + LATENCY_S - new - AHEAD_S) * SR)  # the sample of t + latency on the new clock
        loud = np.nonzero(np.abs(audio[rendered:]) > ONSET)[0]
        assert loud.size and abs(rendered + int(loud[0]) - due) <= BLOCK
    finally:
        core.close()


def test_the_timeline_keeps_each_steps_anchor() -> None:
    core = _live_core(record=False)
    try:
        assert core.timeline() == [(0, 0.0)]
        old = _run(core, 54.0, 1.0)
        assert core.timeline() == [(0, 54.0)]
        first = core.next_sample
        _stepped(core, -35.0, old - 35.0)
        second_t = _run(core, old - 35.0, 0.5) + 7.0
        second = core.next_sample
        _stepped(core, 7.0, second_t)
        [(s0, t0), (s1, t1), (s2, t2)] = core.timeline()
        assert (s0, t0) == (0, 54.0)
        assert s1 == first and t1 == pytest.approx(54.0 + first / SR - 35.0)
        assert s2 == second and t2 == pytest.approx(54.0 + second / SR - 28.0)
        assert core.stats.clock_steps == 2
    finally:
        core.close()


def test_the_takes_sidecar_gives_a_segment_per_timeline(tmp_path: Path) -> None:
    wav = tmp_path / "take.wav"
    settings = load_settings({"role": "sound", "discovery": False, "clock_master": "self"})
    extra = argparse.Namespace(kit="default", wav=wav, device="none", model="modal", block_size=BLOCK, channels=1,
                               reverb=0.0)
    core = make_core(settings, extra)
    try:
        old = _run(core, 54.0, 1.0)
        stepped_at = core.next_sample
        _stepped(core, -35.0, old - 35.0)
        _run(core, old - 35.0, 1.0)
        frames = core.next_sample
    finally:
        core.close()
    meta = json.loads((tmp_path / "take.wav.json").read_text())
    assert meta["frames"] == frames  # nothing recorded is lost
    assert meta["origin_rig_time_s"] == 54.0  # the first sample's, not the new timeline's
    [first, second] = meta["segments"]
    assert first == {"frame": 0, "rig_time_s": 54.0}
    assert second["frame"] == stepped_at
    assert second["rig_time_s"] == pytest.approx(54.0 + stepped_at / SR - 35.0)
