"""``DrummerScene.load_plan`` called directly (not through ``PhysicsCore.load_plan`` or ``splice_plan``) checks every
limb's room first: a plan whose knots, with their lead-in, would pass a track's bound (MAX_TRACK_KNOTS) is refused
with a TargetError naming the limit, and no limb's queued targets change (before, the limbs ahead of the one that
did not fit were cleared and re-queued, and that one was cleared and left with its lead-in)."""

from __future__ import annotations

import numpy as np
import pytest

from common.gesture.plan import GesturePlan, LimbTrajectory
from common.kit import Limb
from common.messages.physics import CartesianTarget, PhysicsReset
from services.physics.core import PhysicsCore
from services.physics.drummer import DrummerScene
from services.physics.targets import TargetError

BOUND = 40
"""Knots per limb track in these tests (monkeypatched: the real bound is 25,920,000)."""

Knots = tuple[list[float], list[list[float]], list[list[float]]]


@pytest.fixture
def scene(drummer: PhysicsCore, monkeypatch: pytest.MonkeyPatch) -> DrummerScene:
    """The shared drummer's scene, reset, every limb track bounded at ``BOUND`` knots, a few targets queued on both
    hands (what a refused plan must leave alone)."""
    drummer.handle(PhysicsReset(time=0.0), 0.0, "test")
    assert isinstance(drummer.scene, DrummerScene)
    scene = drummer.scene
    for track in scene.limb_tracks.values():
        monkeypatch.setattr(track, "max_knots", BOUND)
    for k in range(3):
        for limb in ("left_hand", "right_hand"):
            x, y, z = (float(c) for c in scene.rest_targets[limb])
            drummer.handle(CartesianTarget(limb=limb, time=0.1 * (k + 1), x=x, y=y, z=z + 0.01 * k, vx=0.0, vy=0.0,
                                           vz=0.0), 0.0, "test")
    return scene


def _plan(scene: DrummerScene, knots: dict[str, int], start: float = 0.5) -> GesturePlan:
    """``knots[limb]`` knots per limb (in that order), 10 ms apart from ``start`` seconds, at the limb's rest."""
    trajectories = {}
    for name, n in knots.items():
        times = start + 0.01 * np.arange(n)
        positions = np.repeat(scene.rest_targets[name][None, :], n, axis=0)
        trajectories[Limb(name)] = LimbTrajectory(Limb(name), times, positions, np.zeros((n, 3)))
    return GesturePlan(trajectories=trajectories, strokes=[], start_time=start,
                       end_time=start + 0.01 * (max(knots.values()) - 1))


def _tracks(scene: DrummerScene) -> dict[str, Knots]:
    return {limb: (list(t.times), [v.tolist() for v in t.values], [d.tolist() for d in t.velocities])
            for limb, t in scene.limb_tracks.items()}


@pytest.mark.parametrize("now", [0.0, None])
def test_a_plan_past_a_tracks_bound_is_refused_before_any_limb_changes(scene: DrummerScene,
                                                                      now: float | None) -> None:
    """The right hand's part fits and comes first; the left hand's does not: neither hand's queue may change."""
    lead_in = 0 if now is None else 2  # a hand's start knot and arc apex: the plan starts 0.5 s after now
    before = _tracks(scene)
    too_many = _plan(scene, {"right_hand": 10, "left_hand": BOUND - lead_in + 1})
    with pytest.raises(TargetError, match="MAX_TRACK_KNOTS"):
        scene.load_plan(too_many, start_at=0.5, now=now)
    assert _tracks(scene) == before


def test_the_refusal_names_the_limb_and_the_counts(scene: DrummerScene) -> None:
    with pytest.raises(TargetError) as refused:
        scene.load_plan(_plan(scene, {"right_hand": 10, "left_hand": BOUND - 1}), start_at=0.5, now=0.0)
    assert str(refused.value) == (f"plan has {BOUND - 1} left_hand knots; with the 2 lead-in knots that passes the "
                                  f"limit of {BOUND} knots per track (MAX_TRACK_KNOTS); refused, the queued targets "
                                  "are kept")


@pytest.mark.parametrize("now", [0.0, None])
def test_a_plan_that_fills_a_track_exactly_is_queued(scene: DrummerScene, now: float | None) -> None:
    lead_in = 0 if now is None else 2
    scene.load_plan(_plan(scene, {"right_hand": 10, "left_hand": BOUND - lead_in}), start_at=0.5, now=now)
    assert len(scene.limb_tracks["left_hand"]) == BOUND
    assert len(scene.limb_tracks["right_hand"]) == 10 + lead_in
