"""The trunk under the computed-torque PD during a real groove: the pelvis and spine stay off their torque limits
in most steps and both hands follow their plans.

The upper body (5-12 kg m^2 about the seat's and lumbar's horizontal axes) gets 250-400 N m. At the arms'
15 Hz the trunk's PD asked it for hundreds of rad/s^2 after strokes; clipped joint by joint, the demands set the
pelvis and spine chattering between their limits (a fifth of the steps of these 12 s) and the hands' aim points
dropped under their plans (99th percentile 26 mm). ``ControlParams.trunk_ct_frequency_hz`` runs the trunk's PD slower.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from batteur.render import RenderOptions, prepare
from common.kit import Limb, load_kit
from services.physics.core import PhysicsCore
from services.physics.drummer import DrummerScene

MIDI = Path(__file__).parents[1] / "data" / "groove_drummer1_s2_1_latin-chacarera_157_beat_3-4.mid"
SECONDS = 12.0
START_S = 0.5


@pytest.fixture(scope="module")
def groove_run() -> tuple[float, np.ndarray]:
    """Play the groove's first ``SECONDS``: (share of steps with a trunk torque at its limit, the two hands'
    aim-point errors from their plans every 5 ms, metres)."""
    opts = RenderOptions()
    kit = load_kit(opts.kit)
    _, _, plan = prepare(MIDI, kit, opts)
    core = PhysicsCore(scene="drummer", kit=kit, pose_rate_hz=0)
    scene = core.scene
    assert isinstance(scene, DrummerScene)
    body, controller, client = scene.body, scene.controller, core.world.client
    trunk = np.flatnonzero(controller.group_of == "trunk")
    aims = {side: body.link_index[f"{side}_stick_aim"] for side in ("left", "right")}
    tracks = {side: plan.trajectories[Limb(f"{side}_hand")] for side in aims}
    offset = START_S - plan.start_time
    core.load_plan(plan, start_at=START_S)
    steps = saturated = 0
    errors: list[float] = []
    for k in range(round(START_S * 1000) + 1, round((SECONDS + offset) * 1000) + 1):
        core.step(k / 1000)  # the first call also runs the settling steps before START_S (not counted)
        steps += 1
        saturated += int(np.any(np.abs(controller.last_tau[trunk]) >= body.torque_limit[trunk] - 1e-9))
        if k % 5 == 0:
            for side, link in aims.items():
                aim = np.array(client.getLinkState(body.id, link, computeForwardKinematics=1)[4])
                errors.append(float(np.linalg.norm(aim - tracks[side].sample(k / 1000 - offset).position)))
    core.close()
    return saturated / steps, np.array(errors)


@pytest.mark.slow
def test_the_trunk_stays_off_its_torque_limits_in_most_steps(groove_run: tuple[float, np.ndarray]) -> None:
    share, _ = groove_run
    assert share < 0.18, f"a trunk torque at its limit in {share:.0%} of the steps"


@pytest.mark.slow
def test_both_hands_follow_their_plans_through_the_groove(groove_run: tuple[float, np.ndarray]) -> None:
    _, errors = groove_run
    assert np.sqrt(np.mean(errors**2)) < 0.008
    assert np.quantile(errors, 0.99) < 0.020, f"aim points {1000 * np.quantile(errors, 0.99):.1f} mm off (p99)"
