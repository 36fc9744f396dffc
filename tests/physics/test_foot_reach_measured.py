"""One foot reach for the planner and physics, the one renders measure (common/score/limbs.py ``FOOT_REACH``).

The planner dropped a foot's notes beyond 1.02 m from its hip while physics rested the foot on pedals up to
1.12 m (thigh + shank + foot): a kick 0.60 m further forward (pedal 1.035 m from the hip) played both its kicks
before 7 Dec and none after. Measured: every kick sounds at 1.0355 m, none from 1.044 m; both now use 1.036 m."""

from __future__ import annotations

import math

import pytest

from common.gesture.plan import IssueReason
from common.kit import EventType, Kit, Limb, load_kit
from common.score.events import DrumEvent, Score
from common.score.limbs import FOOT_REACH, distribute, hips
from services.physics.core import PhysicsCore
from services.physics.drummer import DrummerScene


def _kick_forward(dy_m: float) -> Kit:
    """The default kit with its kick and pedal ``dy_m`` metres further from the drummer."""
    kit = load_kit("default", warn=False)
    objects = [o.model_copy(update={"position": (o.position[0], o.position[1] + dy_m, o.position[2])})
               if o.id in ("kick", "kick_pedal") else o for o in kit.objects]
    return kit.model_copy(update={"objects": objects})


def _hip_to_pedal(kit: Kit) -> float:
    return math.dist(kit.effector_target(EventType.BASS, Limb.RIGHT_FOOT)[0], hips(kit)[Limb.RIGHT_FOOT])


@pytest.mark.parametrize(("dy_m", "reached"), [(0.60, True), (0.62, False)])
def test_the_planner_and_physics_reach_the_same_pedals(dy_m: float, reached: bool) -> None:
    kit = _kick_forward(dy_m)
    assert (_hip_to_pedal(kit) <= FOOT_REACH) == reached  # 1.0355 m and 1.052 m
    score = Score([DrumEvent(0.5 * k, EventType.BASS, 0.7) for k in range(2)])
    dropped = [i for i in distribute(score, kit).issues if i.reason == IssueReason.UNREACHABLE]
    assert (dropped == []) == reached
    core = PhysicsCore(scene="drummer", kit=kit, pose_rate_hz=0)
    try:
        assert isinstance(core.scene, DrummerScene)
        assert ("right_foot" in core.scene.rest_targets) == reached  # rests on the pedal it plays
    finally:
        core.close()
