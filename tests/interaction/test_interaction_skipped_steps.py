"""A live physics node that falls behind skips rig time, not steps: its step counter goes on by one while the
contact times jump 20-70 ms (services/physics/core.py). A stick resting on the crash after a score's last note
was then struck again at every skip, each time with the contact's first approach velocity (physics repeats it in
every step): 62-102 crash impacts at 4-8 m/s in 5 s after `batteur rig --score demo`, the recording clipping.
Consecutive physics steps are one contact, whatever the time between them."""

from __future__ import annotations

import pytest

from common.core import Outgoing
from common.kit import load_kit
from common.messages import Contact, Impact
from services.interaction.config import InteractionConfig, RedundancyConfig
from services.interaction.core import InteractionCore

KIT = load_kit("default")
SKIP_S = 0.040
"""Rig time physics skips at once when it falls behind (28-70 ms seen on the rig)."""


def contact(time: float, step: int, instrument: str, part: str, velocity: float) -> Contact:
    return Contact(time=time, step=step, instrument=instrument, part=part, x=0.0, y=0.0, z=0.0,
                   local_x=0.05, local_y=0.0, local_z=0.0, normal_x=0.0, normal_y=0.0, normal_z=1.0,
                   normal_velocity=velocity, impulse=0.001, normal_force=1.0)  # fmt: skip


def resting(steps: int, skip_every: int, skip_s: float = SKIP_S) -> list[tuple[int, float]]:
    """(step, time) of a contact held ``steps`` steps of 1 ms from 10 s, physics skipping ``skip_s`` of rig time
    every ``skip_every`` steps."""
    out, time = [], 10.0
    for i in range(steps):
        out.append((1000 + i, time))
        time += 0.001 + (skip_s if (i + 1) % skip_every == 0 else 0.0)
    return out


def play(stream: list[tuple[int, float]], parts: list[tuple[str, str]]) -> list[Impact]:
    """Deliver each step's contacts (one per (instrument, part), in that order) as a late live node does: the
    receiver's clock runs on through the skipped time before the step after it arrives."""
    core = InteractionCore(kit=KIT, config=InteractionConfig(redundancy=RedundancyConfig(copies=1),
                                                             routes=[{"to": "sound"}]))  # type: ignore[list-item]
    out: list[Outgoing] = []
    last = stream[0][1]
    for step, time in stream:
        for now in [last + 0.001 * k for k in range(1, round((time - last) / 0.001))]:
            out += core.step(now)  # the skipped time passes on the receiver's clock
        for instrument, part in parts:
            out += core.handle(contact(time, step, instrument, part, 8.0), time + 0.0005, "physics")
        out += core.step(time + 0.0005)
        last = time
    return [o.message for o in out if isinstance(o.message, Impact)]


def test_a_stick_resting_on_a_cymbal_while_physics_skips_is_one_impact() -> None:
    impacts = play(resting(400, skip_every=60), [("crash", "right_stick_tip")])
    assert [(i.instrument, i.velocity) for i in impacts] == [("crash", 8.0)]  # was 7: one more at each skip


def test_two_resting_contacts_ended_by_each_others_time_are_one_impact_each() -> None:
    # the beater's step after the skip arrives first: its time ended the stick's contact before the stick's own
    impacts = play(resting(400, skip_every=60), [("kick", "kick_beater"), ("crash", "right_stick_tip")])
    assert sorted(i.instrument for i in impacts) == ["crash", "kick"]


@pytest.mark.parametrize("gap_steps", [2, 30])
def test_a_contact_that_stops_and_starts_again_is_still_a_new_strike(gap_steps: int) -> None:
    first = resting(10, skip_every=1000)
    step, time = first[-1]
    again = [(step + gap_steps + i, time + 0.001 * gap_steps + 0.020 + 0.001 * i) for i in range(10)]
    impacts = play(first + again, [("crash", "right_stick_tip")])
    assert len(impacts) == 2
