"""Bad physics inputs: rejected with a clear error and counted, never lost silently, never taking good data along."""

from __future__ import annotations

import logging
import math

import numpy as np
import pytest

from common.gesture.plan import GesturePlan, LimbTrajectory
from common.kit import Limb
from common.messages import Contact
from common.messages.physics import (
    CartesianTarget,
    JointTarget,
    PhysicsControlMode,
    PhysicsGains,
    PhysicsGrip,
    PhysicsIk,
    PhysicsStrike,
)
from services.physics import node
from services.physics.core import REJECT_LOG_INTERVAL_S, PhysicsCore
from services.physics.drummer import DrummerScene
from services.physics.targets import TargetError


def test_the_strike_scene_rejects_and_counts_the_drummers_messages() -> None:
    """A target or a controller change sent to a strike-scene node does nothing there: it must be refused and
    counted (not dropped unseen, nor reported as the controller in use), and strikes must still play."""
    core = PhysicsCore(scene="strike")
    drummer_only = [
        CartesianTarget(limb="left_hand", time=0.5, x=0.0, y=0.4, z=1.0, vx=0.0, vy=0.0, vz=0.0),
        JointTarget(time=0.5, values=(0.0,) * 114),
        PhysicsControlMode(mode="joint_pd"),
        PhysicsGains(group="all", ks_scale=2.0, kd_scale=1.0),
        PhysicsGrip(hand="left", grip="german"),
        PhysicsIk(damping=0.1, posture_gain=1.0),
    ]
    for message in drummer_only:
        assert [o.message.ADDRESS for o in core.handle(message, 0.0, "test")] == ["/batteur/physics/rejected"]
    assert core.rejected == {type(m).__name__: 1 for m in drummer_only}
    assert core.settings.control == "cartesian"  # not switched: the strike scene has no controller
    core.handle(PhysicsStrike(time=0.1, velocity=3.0), 0.0, "test")
    contacts = [o.message for k in range(1, 201) for o in core.step(k / 1000) if isinstance(o.message, Contact)]
    assert contacts and abs(contacts[0].time - 0.1) < 0.01
    core.close()


def _one_knot_plan(position: np.ndarray, time: float = 0.0) -> GesturePlan:
    traj = LimbTrajectory(Limb.LEFT_HAND, np.array([time]), position[None, :], np.zeros((1, 3)))
    return GesturePlan(trajectories={Limb.LEFT_HAND: traj}, strokes=[])


@pytest.mark.parametrize("start_at", [math.nan, math.inf, 1e17])
def test_a_plan_with_unusable_times_is_refused_and_keeps_the_queued_targets(start_at: float) -> None:
    """load_plan checks every knot before it queues anything: a start time that makes the knot times non-finite
    (or, a huge one, no longer increasing) must not clear the limb's queued targets first."""
    core = PhysicsCore(scene="drummer")
    scene = core.scene
    assert isinstance(scene, DrummerScene)
    rest = scene.rest_targets["left_hand"]
    scene.add_cartesian("left_hand", 0.2, rest + np.array([0.0, 0.0, 0.05]), np.zeros(3), 0.0)
    scene.add_cartesian("left_hand", 0.4, rest, np.zeros(3), 0.0)
    two = LimbTrajectory(Limb.LEFT_HAND, np.array([0.0, 0.5]), np.array([rest, rest]), np.zeros((2, 3)))
    with pytest.raises(TargetError):
        core.load_plan(GesturePlan(trajectories={Limb.LEFT_HAND: two}, strokes=[]), start_at=start_at)
    assert scene.limb_tracks["left_hand"].times == [0.2, 0.4]
    core.load_plan(_one_knot_plan(rest), start_at=0.3)  # a good plan still loads
    assert scene.limb_tracks["left_hand"].times[-1] == pytest.approx(0.3)
    core.close()


def test_a_stream_of_bad_targets_is_counted_but_logged_once_per_interval(caplog: pytest.LogCaptureFixture) -> None:
    """Thousands of bad targets must not write thousands of log lines: one warning per message kind and
    interval, the next one saying how many were not logged; every one is counted."""
    core = PhysicsCore(scene="drummer")
    far = CartesianTarget(limb="right_hand", time=0.5, x=0.0, y=4.0, z=1.0, vx=0.0, vy=0.0, vz=0.0)
    with caplog.at_level(logging.WARNING, logger="batteur.physics"):
        for _ in range(100):
            core.handle(far, 0.0, "test")
        core.handle(JointTarget(time=0.5, values=(0.0,) * 3), 0.0, "test")  # another kind: its own warning
        core.handle(far, REJECT_LOG_INTERVAL_S, "test")
    warnings = [r.getMessage() for r in caplog.records if "rejected" in r.getMessage()]
    assert core.rejected == {"CartesianTarget": 101, "JointTarget": 1}
    assert len(warnings) == 3
    assert "unreachable" in warnings[0] and "JointTarget" in warnings[1]
    assert "+99 more" in warnings[2]
    core.close()


def test_help_lists_the_choices_of_control_grip_and_strike_event(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        node.main(["--help"])
    text = " ".join(capsys.readouterr().out.split())
    for choice in ("joint_spd", "cartesian_pd", "traditional", "german", "HIHATCLOSED"):
        assert choice in text, choice
    assert "pose publishing rate, Hz (0: off)" in text


def test_more_damping_asked_live_never_shakes_the_held_body() -> None:
    """A kd_scale above 1 in the explicit PD may not raise a joint's damping past the explicit damper's stability
    limit: the body holding its rest posture must stay still (before the cap, kd_scale 1.5 made 364 contacts in
    0.5 s, joints at 16 rad/s)."""
    core = PhysicsCore(scene="drummer", control="joint_pd")
    core.handle(PhysicsGains(group="all", ks_scale=1.0, kd_scale=5.0), 0.0, "test")
    scene = core.scene
    assert isinstance(scene, DrummerScene)
    contacts, fastest = 0, 0.0
    for k in range(1, 501):
        contacts += sum(isinstance(o.message, Contact) for o in core.step(k / 1000))
        fastest = max(fastest, float(np.abs(scene.body.state()[1]).max()))
    core.close()
    assert contacts == 0
    assert fastest < 6.0  # rad/s; about 3 with the default gains, 52 before the cap
