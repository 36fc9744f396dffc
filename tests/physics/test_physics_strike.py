"""The strike scene: a stick thrown onto the snare gives one compliant contact with rebound."""

from __future__ import annotations

import math
from typing import ClassVar

import pytest

from common.bus import OfflineRunner
from common.core import Outgoing
from common.messages import Contact, OscMessage, Pose, Skeleton
from common.messages.physics import PhysicsStrike
from services.physics.core import PhysicsCore


def _run(core: PhysicsCore, until_s: float) -> list[Contact]:
    contacts: list[Contact] = []
    for k in range(1, round(until_s * core.rate_hz) + 1):
        for out in core.step(k / core.rate_hz):
            if isinstance(out.message, Contact):
                assert out.to == "interaction"
                contacts.append(out.message)
    return contacts


def _episodes(contacts: list[Contact]) -> list[list[Contact]]:
    episodes: list[list[Contact]] = []
    for c in contacts:
        if episodes and c.step == episodes[-1][-1].step + 1:
            episodes[-1].append(c)
        else:
            episodes.append([c])
    return episodes


def test_one_contact_of_a_few_ms_with_rebound() -> None:
    core = PhysicsCore(scene="strike", strikes=[(0.1, 3.0)])
    contacts = _run(core, 0.098)
    assert contacts == []  # nothing before the strike
    angles = []
    for k in range(99, 141):
        for out in core.step(k / 1000):
            if isinstance(out.message, Contact):
                contacts.append(out.message)
        angles.append(core.world.client.getJointState(core.scene.body, 0)[:2])  # type: ignore[attr-defined]
    episodes = _episodes(contacts)
    assert len(episodes) == 1, [c.step for c in contacts]
    ep = episodes[0]
    duration_s = len(ep) / core.rate_hz
    assert 0.001 <= duration_s <= 0.010
    first = ep[0]
    assert abs(first.time - 0.1) <= 0.0021  # on schedule within two steps
    assert first.instrument == "snare" and first.part == "right_stick_tip"
    assert 2.7 < first.normal_velocity < 3.3  # the approach velocity, m/s
    assert all(c.normal_velocity == first.normal_velocity for c in ep)
    assert first.normal_z > 0.9  # from the head towards the stick
    assert math.hypot(first.local_x, first.local_y) == pytest.approx(0.25 * 0.178, abs=0.01)  # SNARE hit point
    assert abs(first.local_z) < 0.005
    total_impulse = sum(c.impulse for c in ep)
    assert 0.01 < total_impulse < 0.2
    # rebound: after the contact the stick turns away from the head (positive joint velocity)
    after = angles[len(ep) + 3]
    assert after[1] > 0.5


def test_louder_strikes_give_larger_impulses() -> None:
    core = PhysicsCore(scene="strike", strikes=[(0.05, 1.0), (0.25, 3.0), (0.45, 6.0)])
    episodes = _episodes(_run(core, 0.6))
    assert len(episodes) == 3
    impulses = [sum(c.impulse for c in ep) for ep in episodes]
    velocities = [ep[0].normal_velocity for ep in episodes]
    assert impulses[0] < impulses[1] < impulses[2]
    assert velocities[0] < velocities[1] < velocities[2]


def test_same_inputs_same_contacts_bit_for_bit() -> None:
    runs = []
    for _ in range(2):
        core = PhysicsCore(scene="strike", strikes=[(0.05, 2.0), (0.2, 4.5)])
        runs.append([c.model_dump() for c in _run(core, 0.3)])
        core.close()
    assert runs[0] and runs[0] == runs[1]


class _Collector:
    ROLE: ClassVar[str] = "interaction"
    rate_hz = 0.0

    def __init__(self) -> None:
        self.contacts: list[Contact] = []

    def handle(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        if isinstance(message, Contact):
            self.contacts.append(message)
        return []

    def step(self, now: float) -> list[Outgoing]:
        return []


class _Graphics(_Collector):
    ROLE: ClassVar[str] = "graphics"

    def __init__(self) -> None:
        super().__init__()
        self.poses = 0
        self.skeletons: list[Skeleton] = []

    def handle(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        if isinstance(message, Pose):
            self.poses += 1
        if isinstance(message, Skeleton):
            self.skeletons.append(message)
        return []


def test_through_the_offline_bus_with_a_strike_message() -> None:
    core = PhysicsCore(scene="strike")
    sink, graphics = _Collector(), _Graphics()
    runner = OfflineRunner([core, sink, graphics])
    core.handle(PhysicsStrike(time=0.1, velocity=2.5), 0.0, "test")
    runner.run_until(0.2)
    assert sink.contacts and sink.contacts[0].normal_velocity == pytest.approx(2.5, abs=0.3)
    assert 10 <= graphics.poses <= 14  # 60 Hz for 0.2 s
    assert graphics.skeletons and graphics.skeletons[0].names[0] == "right_stick"


def test_bad_strikes_are_rejected_with_a_clear_error() -> None:
    with pytest.raises(ValueError, match="velocity"):
        PhysicsCore(scene="strike", strikes=[(0.1, float("nan"))])
    with pytest.raises(ValueError, match="time"):
        PhysicsCore(scene="strike", strikes=[(-1.0, 2.0)])
    core = PhysicsCore(scene="strike")
    _run(core, 0.05)
    replies = core.handle(PhysicsStrike(time=0.01, velocity=2.0), 0.05, "test")
    assert [o.message.ADDRESS for o in replies] == ["/batteur/physics/rejected"]
    assert core.rejected["PhysicsStrike"] == 1


@pytest.mark.parametrize("speed", [1.0, 3.0, 6.0])
def test_a_closed_hi_hat_gives_one_short_contact_with_rebound_at_any_speed(speed: float) -> None:
    """The strike scene holds a closed hi-hat's pedal down. It stood open (its top above the closed hit point the
    stick is aimed at), so a soft stroke released the stick into the plate: one contact of 80 steps, the stick
    frozen against the plate's motor at 200 N."""
    from common.kit import EventType

    core = PhysicsCore(scene="strike", strikes=[(0.05, speed)], strike_event=EventType.HIHATCLOSED)
    contacts = [c for c in _run(core, 0.12) if "stick" in c.part]  # the plates report their resting contact too
    episodes = _episodes(contacts)
    assert len(episodes) == 1, [c.step for c in contacts]
    assert 0.001 <= len(episodes[0]) / core.rate_hz <= 0.010
    first = episodes[0][0]
    # the closed top stands about 3 mm above the kit's hit point: a 1 m/s stroke lands 4 ms early, 3 m/s on time
    assert first.instrument == "hihat" and abs(first.time - 0.05) <= 0.0051
    assert first.normal_velocity == pytest.approx(speed, rel=0.1)
    assert core.world.client.getJointState(core.scene.body, 0)[1] > 0.0  # type: ignore[attr-defined]  # rebounds
    core.close()
