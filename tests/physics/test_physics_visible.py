"""What a researcher sees of the physics service from outside: the body built (``--show-body``, the start line), the
controller's counters (limit violations, torque saturation: report.json and the node's log), the live switches
(logged, rate-limited; gains too low for the limits to hold warned), and settings refused with their unit.

Before: nothing printed the body (segments, masses, DOF, torque limits, gains, limits' sources); the counters were
not exposed (saturation not counted); ``/batteur/physics/control``, ``gains``, ``grip`` were accepted in silence
(``gains arms 0 0`` switched the joint limits off unsaid); ``--height-m 182`` said "must be at most 2.2" without a
unit, ``--control-rate-hz 3000`` was accepted and ran at 1 kHz.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Iterator
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from pydantic import ValidationError

from batteur import render
from common.messages.physics import JointTarget, PhysicsControlMode, PhysicsGains, PhysicsGrip, PhysicsIk
from services.physics.anthropometry import anthropometry
from services.physics.body_table import body_summary
from services.physics.core import PhysicsCore
from services.physics.drummer import LOW_KS_SCALE, DrummerScene
from services.physics.node import COUNTS_LOG_PERIOD_S, LivePhysicsCore, PhysicsNodeSettings, main

SENDER = "127.0.0.1:9"


@pytest.fixture(scope="module")
def core() -> Iterator[PhysicsCore]:
    core = PhysicsCore(scene="drummer", pose_rate_hz=0, control_rate_hz=300)
    try:
        yield core
    finally:
        core.close()


def scene_of(core: PhysicsCore) -> DrummerScene:
    assert isinstance(core.scene, DrummerScene)
    return core.scene


def said(caplog: pytest.LogCaptureFixture, level: int = logging.INFO) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name == "batteur.physics" and r.levelno == level]


def test_live_switches_are_said_once_from_what_to_what(core: PhysicsCore, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger="batteur.physics")
    scene = scene_of(core)
    assert core.handle(PhysicsControlMode(mode="joint_pd"), 0.0, SENDER) == []
    assert core.handle(PhysicsGains(group="arms", ks_scale=2.0, kd_scale=1.5), 0.0, SENDER) == []
    assert core.handle(PhysicsGrip(hand="both", grip="french"), 0.0, SENDER) == []
    assert core.handle(PhysicsIk(damping=0.05, posture_gain=1.0), 0.0, SENDER) == []
    assert said(caplog) == [
        "control mode cartesian -> joint_pd",
        "gains arms: ks x1 -> x2, kd x1 -> x1.5 (of the defaults)",
        "grip left american, right american -> left french, right french (hand both)",
        "IK damping 0.02 -> 0.05 m, posture gain 2 -> 1 1/s"]
    caplog.clear()
    for k in range(5):  # a stream: at most one line a second of rig time (per group), the rest counted
        scene.handle(PhysicsGains(group="all", ks_scale=1.0 + k / 10, kd_scale=1.0), 0.5 + k / 10)
    scene.handle(PhysicsGains(group="all", ks_scale=1.0, kd_scale=1.0), 1.6)
    assert said(caplog) == ["gains all: ks x1-2 -> x1, kd x1-1.5 -> x1 (of the defaults)",
                            "gains all: ks x1.4 -> x1, kd x1 -> x1 (of the defaults) (+4 more since the last report)"]
    caplog.clear()
    scene.handle(PhysicsGains(group="arms", ks_scale=2.0, kd_scale=1.5), 3.0)
    scene.handle(PhysicsGains(group="all", ks_scale=1.0, kd_scale=1.0), 5.0)  # the DOF differed: their range
    assert said(caplog)[1] == "gains all: ks x1-2 -> x1, kd x1-1.5 -> x1 (of the defaults)"
    assert said(caplog, logging.WARNING) == []


def test_gains_too_low_for_the_limits_to_hold_are_warned(core: PhysicsCore,
                                                         caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger="batteur.physics")
    scene = scene_of(core)
    scene.handle(PhysicsControlMode(mode="cartesian"), 5.0)  # the mode measured (the module's core is shared)
    scene.handle(PhysicsGains(group="arms", ks_scale=LOW_KS_SCALE, kd_scale=1.0), 10.0)
    assert said(caplog, logging.WARNING) == []
    scene.handle(PhysicsGains(group="arms", ks_scale=0.0, kd_scale=0.0), 20.0)
    warned = said(caplog, logging.WARNING)
    assert len(warned) == 1 and warned[0].startswith("gains arms: ks x0 is below x0.15 in cartesian control: the "
                                                     "joint limits'")
    scene.handle(PhysicsGains(group="all", ks_scale=1.0, kd_scale=1.0), 30.0)


def test_switches_of_other_groups_are_said_and_a_streams_latest_too(core: PhysicsCore,
                                                                    caplog: pytest.LogCaptureFixture) -> None:
    """One rate limit per kind hid switches: a setup burst (trunk, head, arms, legs 1 ms apart) logged only trunk,
    low arms then legs 0.2 s later warned only arms, and a slider's last value (x0.3) was never said. Now per group
    (or hand), and a held stream's latest is said once the interval has passed (the node's step loop flushes it)."""
    caplog.set_level(logging.INFO, logger="batteur.physics")
    scene = scene_of(core)
    scene.handle(PhysicsControlMode(mode="cartesian"), 95.0)  # the mode measured (the module's core is shared)
    caplog.clear()
    for k, group in enumerate(("trunk", "head", "arms", "legs")):
        scene.handle(PhysicsGains(group=group, ks_scale=0.5, kd_scale=0.5), 110.0 + k * 0.001)
    assert [line.split(":")[0] for line in said(caplog)] == ["gains trunk", "gains head", "gains arms", "gains legs"]
    caplog.clear()
    scene.handle(PhysicsGains(group="arms", ks_scale=0.1, kd_scale=1.0), 120.0)
    scene.handle(PhysicsGains(group="legs", ks_scale=0.05, kd_scale=1.0), 120.2)
    assert [line.split(":")[0] for line in said(caplog, logging.WARNING)] == ["gains arms", "gains legs"]
    caplog.clear()
    for k in range(30):  # a slider 1.0 -> 0.3 over 0.5 s, then nothing
        scene.handle(PhysicsGains(group="all", ks_scale=1.0 - 0.7 * k / 29, kd_scale=1.0), 130.0 + k / 60)
    scene.flush_switches(130.9)  # not yet: within the interval of the first line
    assert len(said(caplog)) == 1
    scene.flush_switches(131.1)
    assert said(caplog)[1].startswith("gains all: ks x0.324138 -> x0.3, kd x1 -> x1 (of the defaults) (the latest "
                                      "of 29 since the last report)")
    scene.flush_switches(140.0)  # said once
    assert len(said(caplog)) == 2


def test_the_live_node_says_a_held_switch_from_its_step_loop(caplog: pytest.LogCaptureFixture) -> None:
    """With no message after a slider's stream its last value was never said: the node's steps say it."""
    caplog.set_level(logging.INFO, logger="batteur.physics")
    live = LivePhysicsCore(planner="thread", scene="drummer", pose_rate_hz=0, mode="live")
    try:
        live.step(1.0)  # the switches are said at the core's time
        for k in range(3):
            live.handle(PhysicsGains(group="all", ks_scale=1.0 - 0.1 * k, kd_scale=1.0), 1.0 + k / 60, SENDER)
        live.step(1.5)  # within the interval
        assert [line for line in said(caplog) if line.startswith("gains all")] == [
            "gains all: ks x1 -> x1, kd x1 -> x1 (of the defaults)"]
        live.step(2.2)  # live: behind, it skips to now
        assert said(caplog)[-1] == ("gains all: ks x0.9 -> x0.8, kd x1 -> x1 (of the defaults) (the latest of 2 "
                                    "since the last report)")
    finally:
        live.close()


def test_joint_pd_is_warned_only_below_what_it_was_measured_to_hold(core: PhysicsCore,
                                                                   caplog: pytest.LogCaptureFixture) -> None:
    """joint_pd held the limits down to x0.05 (docs/physics.md, "Live gains"): x0.1 was warned as in cartesian."""
    caplog.set_level(logging.INFO, logger="batteur.physics")
    scene = scene_of(core)
    scene.handle(PhysicsControlMode(mode="joint_pd"), 240.0)
    scene.handle(PhysicsGains(group="arms", ks_scale=0.1, kd_scale=1.0), 241.5)
    scene.handle(PhysicsGains(group="arms", ks_scale=0.05, kd_scale=1.0), 243.0)
    assert said(caplog, logging.WARNING) == []
    scene.handle(PhysicsGains(group="arms", ks_scale=0.0, kd_scale=1.0), 245.0)
    warned = said(caplog, logging.WARNING)
    assert len(warned) == 1 and warned[0].startswith("gains arms: ks x0 is below x0.05 in joint_pd control")
    scene.handle(PhysicsControlMode(mode="cartesian"), 246.0)
    scene.handle(PhysicsGains(group="all", ks_scale=1.0, kd_scale=1.0), 247.0)


def test_the_torque_saturation_counter_counts_dof_at_their_limit_every_step(core: PhysicsCore) -> None:
    """Stiff gains and a joint target far from the posture: torques clip, on full updates (every 3 steps at
    300 Hz) and on the steps between alike; each step adds the DOF at their limit."""
    scene = scene_of(core)
    controller = scene.controller
    core.handle(PhysicsControlMode(mode="joint_pd"), core.time, SENDER)
    core.handle(PhysicsGains(group="all", ks_scale=20.0, kd_scale=1.0), core.time, SENDER)
    far = np.clip(scene.rest + 0.5, scene.body.lower, scene.body.upper)
    core.handle(JointTarget(time=core.time + 0.001, values=[*far, *np.zeros(len(far))]), core.time, SENDER)
    increments = []
    start = round(core.time * 1000)
    for k in range(start + 1, start + 10):
        before = controller.torque_saturated
        core.step(k / 1000)
        at_limit = int(np.count_nonzero(np.abs(controller.last_tau) >= scene.body.torque_limit))
        assert controller.torque_saturated - before == at_limit
        increments.append(at_limit)
    assert sum(increments) > 0
    core.handle(PhysicsGains(group="all", ks_scale=1.0, kd_scale=1.0), core.time, SENDER)
    core.handle(PhysicsControlMode(mode="cartesian"), core.time, SENDER)


def test_the_body_is_said_at_start_with_its_real_control_rate(core: PhysicsCore) -> None:
    line = body_summary(scene_of(core))
    assert line.startswith("drummer body: 1.75 m, 73 kg (73 kg of segments), 57 DOF, ")
    assert "control updates at 333.3 Hz (every 3 of the 1000 Hz physics steps; 300 Hz asked)" in line


def test_show_body_prints_the_body_as_built(capsys: pytest.CaptureFixture[str]) -> None:
    flags = ["--height-m", "1.82", "--mass-kg", "80", "--no-discovery", "--no-oscquery"]
    with pytest.raises(SystemExit) as stop:
        main([*flags, "--show-body", "json"])
    assert stop.value.code == 0
    body = json.loads(capsys.readouterr().out)
    table = anthropometry(1.82, 80.0)
    assert (body["height_m"], body["mass_kg"], body["dof"]) == (1.82, 80.0, 57)
    assert body["segments"]["thigh"] == {"length_m": round(table.segments["thigh"].length_m, 4),
                                         "mass_kg": round(table.segments["thigh"].mass_kg, 3), "count": 2}
    assert body["segments_mass_kg"] == pytest.approx(80.0, abs=0.01)
    elbow = body["joints"]["right_elbow"]
    assert elbow["torque_limit_nm"] == pytest.approx(80.0 * 80 / 73, abs=0.01)
    assert len(elbow["ks_nm_per_rad"]) == 3 and min(elbow["ks_nm_per_rad"]) > 0
    assert body["joints"]["seat"]["limits_source"] == "anatomical"
    assert body["joints"]["right_hip"]["quaternion_limit"] is True
    with pytest.raises(SystemExit):
        main([*flags, "--show-body"])
    text = capsys.readouterr().out
    assert text.startswith("drummer 1.82 m, 80 kg asked; segments 80 kg in all; 57 DOF")
    assert "length m" in text and "mass kg" in text and "torque N m" in text and "ks x/y/z N m/rad" in text
    assert sum(line.startswith(("left_", "right_")) for line in text.splitlines()) == 14


def test_the_node_logs_its_counters_when_they_grow(caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger="batteur.physics")
    controller = SimpleNamespace(limit_violations=0, torque_saturated=0)
    live = SimpleNamespace(scene=SimpleNamespace(controller=controller), _counts_said=None)
    LivePhysicsCore._say_counts(live, 0.0)  # type: ignore[arg-type]
    controller.limit_violations, controller.torque_saturated = 5, 7
    LivePhysicsCore._say_counts(live, COUNTS_LOG_PERIOD_S / 2)  # type: ignore[arg-type]
    assert said(caplog) == []
    LivePhysicsCore._say_counts(live, COUNTS_LOG_PERIOD_S)  # type: ignore[arg-type]
    LivePhysicsCore._say_counts(live, 2 * COUNTS_LOG_PERIOD_S)  # type: ignore[arg-type]  # unchanged: not said
    assert said(caplog) == ["physics controller over the last 60 s: 5 limit violations (joint-updates outside their "
                            "ellipsoid), 7 torque-saturated DOF-steps (5 and 7 since the start)"]


def test_report_json_has_the_controllers_counters(tmp_path: Path) -> None:
    score = tmp_path / "snare.txt"
    score.write_text("tempo 120\nmeter 4/4\nSN |x...|\n", encoding="utf-8")
    out = tmp_path / "out"
    assert render.main([str(score), "-o", str(out), "--quiet"]) == 0
    physics = json.loads((out / "report.json").read_text(encoding="utf-8"))["physics"]
    assert isinstance(physics["limit_violations"], int) and physics["limit_violations"] >= 0
    assert isinstance(physics["torque_saturated"], int) and physics["torque_saturated"] >= 0


def test_settings_refused_say_their_unit_and_the_real_rate() -> None:
    with pytest.raises(ValidationError, match=r"must be 1.2 to 2.2 metres; did you mean 1.82 m\?"):
        PhysicsNodeSettings(height_m=182, discovery=False)
    with pytest.raises(ValidationError, match=r"must be 1.2 to 2.2 metres \["):
        PhysicsNodeSettings(height_m=3, discovery=False)
    with pytest.raises(ValidationError, match="--control-rate-hz 3000 is above the physics step rate, 1000 Hz"):
        PhysicsNodeSettings(control_rate_hz=3000, discovery=False)
    assert PhysicsNodeSettings(rate_hz=2000, control_rate_hz=2000, discovery=False).control_rate_hz == 2000
