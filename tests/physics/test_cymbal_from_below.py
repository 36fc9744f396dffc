"""A stick under a cymbal's plate whose target is over it does not press the plate up from below.

On the live rig a late node's stick cut across under the crash, its target over the plate: the stick was pulled up
into the plate's underside and, the target following the plate's swing ("Aiming at a swinging cymbal",
docs/physics.md), held it tilted up, pressed, for seconds (many crash hits or one long contact). The stick now goes
out from under the plate and around its rim first (``DrummerScene._out_from_under``).

The reproduction is deterministic: an offline core, the right stick parked under the crash by its target, then its
target jumping over the plate (as a late node's target jumps ahead) and held there.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest

from common.messages import Contact
from services.physics import drummer
from services.physics.body import LIMBS
from services.physics.core import PhysicsCore
from services.physics.drummer import DrummerScene
from services.physics.kernels import stick_under_plate

HAND = "right_hand"
PARK_BELOW_M = 0.06
"""The parked target: this far under the crash's plate (the bead's lowest point), 0.6 of its radius from the axis,
toward the drummer, metres."""
OVER_M = 0.06
"""The target it then jumps to: this far over the same point of the plate, metres."""
JUMP_S = 2.0
END_S = 5.0


def _crash(core: PhysicsCore) -> int:
    return [obj.id for obj in core.kit.objects if obj.kind == "cymbal"].index("crash")


@pytest.fixture(scope="module")
def under_the_crash() -> Iterator[tuple[list[Contact], np.ndarray, np.ndarray]]:
    """(the right stick's crash contacts, its bead at the end, its target then), world metres."""
    core = PhysicsCore(scene="drummer", pose_rate_hz=0)
    scene = core.scene
    assert isinstance(scene, DrummerScene)
    hinges = scene.kit_bodies.cymbal_hinges
    assert hinges is not None
    k = _crash(core)

    def on_crash(z_m: float) -> np.ndarray:
        return hinges.centre[k] + hinges.rotation[k] @ np.array([0.0, -0.6 * hinges.radius[k], z_m])

    park, over = on_crash(-PARK_BELOW_M), on_crash(OVER_M)
    rest = scene.current_targets()[HAND]
    still = np.zeros(3)
    # down from the rest over the hi-hat, then across under the plate, well below it
    scene.add_cartesian(HAND, 0.6, np.array([rest[0], rest[1], park[2] - 0.05]), still, 0.0)
    scene.add_cartesian(HAND, 1.2, park, still, 0.0)
    scene.add_cartesian(HAND, JUMP_S, park, still, 0.0)
    scene.add_cartesian(HAND, JUMP_S + 0.001, over, still, 0.0)
    scene.add_cartesian(HAND, END_S + 1.0, over, still, 0.0)
    contacts: list[Contact] = []
    try:
        for ms in range(1, round(END_S * 1000) + 1):
            contacts += [o.message for o in core.step(ms / 1000) if isinstance(o.message, Contact)
                         and o.message.instrument == "crash" and o.message.part.startswith("right_stick")]
        bead = scene.body.effector_pos[LIMBS.index(HAND)] - scene.target_offset[HAND]
    finally:
        core.close()
    yield contacts, bead, over


def test_a_stick_under_the_crash_does_not_press_it_up_from_below(
        under_the_crash: tuple[list[Contact], np.ndarray, np.ndarray]) -> None:
    contacts, _, _ = under_the_crash
    assert all(c.time > JUMP_S for c in contacts)  # parked clear of the plate
    # before: the stick rose into the plate's underside and held it tilted up to its hinge's limit (0.6 rad),
    # pressed, from 2.007 s to the end (2994 steps of contact); now it goes around the rim without touching it
    assert len(contacts) <= 20, (len(contacts), contacts[:1])


def test_the_stick_gets_over_the_crash_to_its_target(
        under_the_crash: tuple[list[Contact], np.ndarray, np.ndarray]) -> None:
    _, bead, over = under_the_crash
    assert np.linalg.norm(bead - over) < 0.01, (bead, over)


def test_a_stick_striking_a_plate_from_above_is_not_taken_for_one_under_it() -> None:
    """Striking a cymbal, the bead passes below its plane as the hinge angles last read (4 ms before) have it, and
    its target then rises: that is a stroke's rebound, not a stick under the plate (the demo's final crash, 6.4 m/s,
    7 ms of contact, would have been held down 26 ms). A bead that came to the plate from below is under it."""
    core = PhysicsCore(scene="drummer", pose_rate_hz=0)
    try:
        scene = core.scene
        assert isinstance(scene, DrummerScene)
        hinges = scene.kit_bodies.cymbal_hinges
        assert hinges is not None
        k = _crash(core)
        r = float(hinges.radius[k])

        def world(x: float, y: float, z: float) -> np.ndarray:
            return hinges.centre[k] + hinges.rotation[k] @ np.array([x, y, z])

        wrist, aim = world(0.0, -r - 0.3, 0.15), world(0.0, -0.8 * r, 0.05)  # the rebound: up over the plate
        args = (hinges.centre, hinges.rotation, hinges.radius, np.zeros_like(hinges.angles))
        sides = np.zeros(len(hinges.radius), dtype=np.int64)
        rule = (drummer._STICK_SAMPLES, drummer.CYMBAL_UNDER_MARGIN_M, drummer.CYMBAL_UNDER_CLEAR_M)
        assert stick_under_plate(world(0.0, -0.8 * r, 0.03), wrist, aim, *args, sides, *rule) == -1  # coming down on it
        assert stick_under_plate(world(0.0, -0.8 * r, -0.01), wrist, aim, *args, sides, *rule) == -1  # through, as read
        sides[:] = 0
        assert stick_under_plate(world(0.0, -r - 0.06, -0.03), wrist, aim, *args, sides, *rule) == -1  # beside, below
        assert stick_under_plate(world(0.0, -0.8 * r, -0.01), wrist, aim, *args, sides, *rule) == k  # then under it
    finally:
        core.close()
