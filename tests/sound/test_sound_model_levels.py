"""Switching an instrument between the modal, sample and synth models keeps its level: the same strike (the kit's
own strike point, at 0.5, 2 and 6 m/s) has the same RMS over its first 200 ms within 1.5 dB."""

from __future__ import annotations

import functools

import numpy as np
import pytest
from sound_helpers import impact

from common.kit import EventType, load_kit
from services.sound.core import SoundCore, SoundSettings

VELOCITIES = (0.5, 2.0, 6.0)
GAP_S = 3.0  # between strikes of one instrument, softest first: the previous one's tail is 20 dB down or more
WINDOW_S = 0.2  # about the ear's integration time for loudness
KIT = load_kit("default")


def _spec(event: EventType, **changes: object) -> tuple[str, str, float, float]:
    """(instrument, zone, r/a, theta) of the kit's strike for ``event``, with ``changes``."""
    e = KIT.events[event].model_copy(update=changes)
    return e.object, e.zone, e.r, e.theta


STRIKES = {e.name: _spec(e) for e in (
    EventType.BASS, EventType.SNARE, EventType.RIM, EventType.HIGHTOM, EventType.MIDTOM, EventType.FLOORTOM,
    EventType.CRASH, EventType.RIDE, EventType.RIDEBELL, EventType.SPLASH, EventType.CHINA, EventType.COWBELL,
    EventType.HIHATOPEN)}
STRIKES["RIMSHOT"] = _spec(EventType.SNARE, zone="rimshot", r=0.9)
# each group's instruments struck together (each renders into its own bus), one strike per instrument
GROUPS = (("BASS", "SNARE", "HIGHTOM", "MIDTOM", "FLOORTOM", "CRASH", "RIDE", "SPLASH", "CHINA", "COWBELL",
           "HIHATOPEN"), ("RIM", "RIDEBELL"), ("RIMSHOT",))
# what each model levels (the hi-hat's synthesis and its closed sample follow other velocity laws: docs/sound.md)
LEVELLED = {"synth": set(STRIKES) - {"HIHATOPEN"}, "sample": set(STRIKES)}
SOFT_EXEMPT = {("sample", "COWBELL")}  # its velocity low-pass: -2.6 dB at 0.5 m/s (docs/sound.md)


@functools.cache
def _levels(model: str, group: int) -> dict[tuple[str, float], float]:
    """RMS, dB, of the first WINDOW_S of each strike of ``group`` at each velocity, rendered with ``model``."""
    core = SoundCore(SoundSettings(latency=0.0, use_pyo=False, model=model), KIT)
    names = GROUPS[group]
    buses: dict[str, list[np.ndarray]] = {STRIKES[n][0]: [] for n in names}

    def keep(_: np.ndarray) -> None:  # each instrument's own output, before the mix
        for inst, blocks in buses.items():
            bus = core._bus.get(inst)
            blocks.append(np.zeros(core.block) if bus is None else bus.astype(np.float64))

    core.on_block = keep
    try:
        seq = 0
        for k, v in enumerate(VELOCITIES):
            for name in names:
                inst, zone, r, theta = STRIKES[name]
                seq += 1
                core.handle(impact(seq, k * GAP_S, inst, velocity=v, r=r, theta=theta, zone=zone), 0.0, "t")
        core.render(len(VELOCITIES) * GAP_S)
    finally:
        core.close()
    out = {}
    n = int(WINDOW_S * core.sample_rate)
    for name in names:
        audio = np.concatenate(buses[STRIKES[name][0]])
        for k, v in enumerate(VELOCITIES):
            start = int(round(k * GAP_S * core.sample_rate))
            out[(name, v)] = 10.0 * np.log10(np.mean(audio[start:start + n] ** 2))
    return out


@pytest.mark.parametrize("model", ["synth", "sample"])
def test_a_strike_is_as_loud_with_each_model(model: str) -> None:
    off = {}
    for group in range(len(GROUPS)):
        modal, other = _levels("modal", group), _levels(model, group)
        for (name, v), level in other.items():
            if name in LEVELLED[model] and not (v < 1.0 and (model, name) in SOFT_EXEMPT):
                off[f"{name} {v} m/s"] = round(level - modal[(name, v)], 2)
    assert len(off) >= 35
    # was: synth 10.8 dB above modal on the snare, 11.5 on the kick, 12-13 on the toms, 7 on the crash;
    # sample 12 on the kick, 14 on the high tom, 12 on the ride, 20 on the snare's rim
    assert all(abs(d) <= 1.5 for d in off.values()), {k: d for k, d in off.items() if abs(d) > 1.5}
