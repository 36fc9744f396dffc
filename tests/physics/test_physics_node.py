"""The physics node builds a live core from its settings and refuses bad ones."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest

from services.physics.node import PhysicsNodeSettings, main, make_core


def test_make_core_builds_a_live_strike_core_that_skips_when_behind() -> None:
    settings = PhysicsNodeSettings(scene="strike", discovery=False, strike_period=0.5, strike_velocity=2.0)
    core = make_core(settings, argparse.Namespace())
    assert core.ROLE == "physics" and core.settings.mode == "live" and core.rate_hz == 1000.0
    core.step(0.0)
    core.step(10.0)  # 10 s behind: simulates at most max_catchup_steps, skips the rest, counts it
    assert core.skipped_steps == 10_000 - core.settings.max_catchup_steps
    # skipped steps are no late events (batteur ls's late column grew by ~700 a second while nothing played)
    assert core.late == 0 and core.overruns == 1
    core.close()


def test_bad_kit_is_a_clear_error() -> None:
    with pytest.raises(ValueError, match="no kit file"):
        make_core(PhysicsNodeSettings(scene="strike", kit="no-such-kit", discovery=False), argparse.Namespace())


def test_show_settings(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--show-settings", "--scene", "strike", "--no-discovery"]) == 0
    assert '"scene": "strike"' in capsys.readouterr().out


def test_a_step_rate_below_the_default_control_rate_starts(capsys: pytest.CaptureFixture[str],
                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    """``--rate-hz 500`` (or BATTEUR_RATE_HZ=500, as a rig passes it) was refused for the default control rate,
    1000 Hz, that no one gave: the control rate is the step rate then, as --show-settings says; a control rate
    given above the step rate is still refused."""
    assert main(["--show-settings", "--rate-hz", "500", "--no-discovery"]) == 0
    assert '"control_rate_hz": 500.0' in capsys.readouterr().out
    monkeypatch.setenv("BATTEUR_RATE_HZ", "500")
    assert main(["--show-settings", "--no-discovery"]) == 0
    assert '"control_rate_hz": 500.0' in capsys.readouterr().out
    assert main(["--show-settings", "--control-rate-hz", "1000", "--no-discovery"]) == 2
    assert "--control-rate-hz 1000 is above the physics step rate, 500 Hz" in capsys.readouterr().err
    monkeypatch.delenv("BATTEUR_RATE_HZ")
    assert PhysicsNodeSettings(rate_hz=2000, discovery=False).control_rate_hz == 1000  # below: the default kept


def test_motion_capture_files_of_the_node_are_clear_errors(tmp_path: Path) -> None:
    """--limits-from and --skeleton-bvh (or BATTEUR_LIMITS_FROM, comma-separated): a file that is not there is a
    clear error at start, not a traceback."""
    missing = tmp_path / "none.bvh"
    settings = PhysicsNodeSettings.model_validate({"limits_from": f"punch, {missing}", "discovery": False})
    assert settings.limits_from == ["punch", str(tmp_path / "none.bvh")]
    with pytest.raises(ValueError, match="no BVH file"):
        make_core(settings, argparse.Namespace())
    with pytest.raises(ValueError, match="none.bvh: no such file"):
        make_core(PhysicsNodeSettings(skeleton_bvh=str(tmp_path / "none.bvh"), discovery=False), argparse.Namespace())


def test_a_live_core_starts_at_the_rig_time_of_its_first_step_without_counting_it_late() -> None:
    """The rig clock runs from the launch; the node builds its scene first (2-3 s), so its loop's first step comes
    at rig time 2-3 s. That is where the simulation starts, not steps it fell behind (its skipped steps)."""
    settings = PhysicsNodeSettings(scene="strike", discovery=False, strike_period=0.5, strike_velocity=2.0)
    core = make_core(settings, argparse.Namespace())
    core.step(2.9604)
    assert core.time == pytest.approx(2.960, abs=1e-9)
    assert core.skipped_steps == 0 and core.late == 0 and core.overruns == 0
    core.step(3.0)  # 40 steps later: caught up, none skipped
    assert core.time == pytest.approx(3.0, abs=1e-9) and core.skipped_steps == 0
    core.step(13.0)  # then falling 10 s behind is counted as before
    assert core.skipped_steps == 10_000 - core.settings.max_catchup_steps and core.late == 0  # no note late
    core.close()


def test_a_skeleton_without_joints_found_by_name_is_refused_at_start(tmp_path: Path,
                                                                     capsys: pytest.CaptureFixture[str]) -> None:
    """--skeleton-bvh with every joint renamed (none found by its usual BVH name): the node started with de Leva's
    body, silently; it is refused as batteur render refuses it, exit 1 as a file the node cannot use."""
    import signal

    from common.exit_status import InputError

    anon = tmp_path / "anon.bvh"
    anon.write_text("HIERARCHY\nROOT J1\n{\n OFFSET 0 0 0\n CHANNELS 3 Zrotation Xrotation Yrotation\n JOINT J2\n {\n"
                    "  OFFSET 0 50 0\n  CHANNELS 3 Zrotation Xrotation Yrotation\n  End Site\n  {\n   OFFSET 0 10 0\n"
                    "  }\n }\n}\nMOTION\nFrames: 2\nFrame Time: 0.03\n0 0 0 0 0 0\n0 0 0 5 0 0\n", encoding="utf-8")
    says = f"{anon}: no arm, leg or trunk joints found by their usual BVH names"  # render's, after "--skeleton-bvh: "
    with pytest.raises(InputError, match=says):
        make_core(PhysicsNodeSettings(skeleton_bvh=str(anon), discovery=False), argparse.Namespace())
    handler = signal.getsignal(signal.SIGINT)
    try:
        assert main(["--skeleton-bvh", str(anon), "--no-discovery", "--no-oscquery"]) == 1
    finally:
        signal.signal(signal.SIGINT, handler)
    assert says in capsys.readouterr().err
