"""The drummer and kit options ``batteur render`` and ``batteur physics`` share take either command's spelling
(``--height`` / ``--height-m``, ``--mass`` / ``--mass-kg``, ``--control-rate`` / ``--control-rate-hz``, ``--event`` /
``--strike-event``): a flag copied from one command to the other was an argparse error. Parse level only."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from batteur import render
from services.physics import node

SHARED = [  # render's dest, physics' setting, render's flag, physics' flag, value given, value read
    ("height", "height_m", "--height", "--height-m", "1.8", 1.8),
    ("mass", "mass_kg", "--mass", "--mass-kg", "81", 81.0),
    ("control_rate", "control_rate_hz", "--control-rate", "--control-rate-hz", "500", 500.0),
    ("event", "strike_event", "--event", "--strike-event", "RIDE", "RIDE"),
]


def _physics_settings(argv: list[str], capsys: pytest.CaptureFixture[str]) -> dict[str, object]:
    """The physics node's settings from ``argv`` (``--show-settings``: parsed and checked, nothing run)."""
    capsys.readouterr()
    assert node.main([*argv, "--show-settings"]) == 0
    settings: dict[str, object] = json.loads(capsys.readouterr().out)
    return settings


@pytest.mark.parametrize("dest,setting,render_flag,physics_flag,text,value", SHARED)
@pytest.mark.parametrize("spelling", ["render", "physics"])
def test_each_spelling_works_in_batteur_physics(dest: str, setting: str, render_flag: str, physics_flag: str,
                                                text: str, value: object, spelling: str,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    flag = render_flag if spelling == "render" else physics_flag
    assert _physics_settings([flag, text], capsys)[setting] == value


@pytest.mark.parametrize("dest,setting,render_flag,physics_flag,text,value", SHARED)
@pytest.mark.parametrize("spelling", ["render", "physics"])
def test_each_spelling_works_in_batteur_render(dest: str, setting: str, render_flag: str, physics_flag: str,
                                               text: str, value: object, spelling: str) -> None:
    flag = render_flag if spelling == "render" else physics_flag
    args = render.build_parser().parse_args(["score.txt", "-o", "out", flag, text])
    assert getattr(args, dest) == value


def test_render_options_take_physics_spellings() -> None:
    args = render.build_parser().parse_args(["score.txt", "-o", "out", "--height-m", "1.6", "--mass-kg", "60",
                                             "--control-rate-hz", "250"])
    opts = render.options_from(args)
    assert (opts.height_m, opts.mass_kg, opts.control_rate_hz) == (1.6, 60.0, 250.0)


def test_help_names_one_primary_flag_and_the_other_spelling(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        node.main(["--help"])
    physics_help = " ".join(capsys.readouterr().out.split())  # unwrapped
    for _, _, render_flag, physics_flag, _, _ in SHARED:
        assert physics_flag in physics_help and f"({render_flag} too, as batteur render)" in physics_help
        assert f"[{render_flag} " not in physics_help  # the usage line names the node's own flag only
    render_help = " ".join(render.build_parser().format_help().split())
    for _, _, render_flag, physics_flag, _, _ in SHARED:
        assert f"{render_flag} " in render_help and f"{physics_flag} " in render_help


def test_asymmetric_limits_in_both_commands(capsys: pytest.CaptureFixture[str]) -> None:
    assert _physics_settings(["--limits-from", "kick", "--asymmetric-limits"], capsys)["asymmetric_limits"] is True
    assert _physics_settings(["--limits-from", "kick"], capsys)["asymmetric_limits"] is False
    args = render.build_parser().parse_args(["score.txt", "-o", "out", "--limits-from", "kick",
                                             "--asymmetric-limits"])
    assert render.options_from(args).asymmetric_limits is True
    assert render.options_in_vain(args) == []
    with pytest.raises(SystemExit):
        node.main(["--help"])
    assert "--asymmetric-limits" in capsys.readouterr().out
    assert "--asymmetric-limits" in render.build_parser().format_help()


def test_asymmetric_limits_without_clips_is_said_to_do_nothing(tmp_path: Path) -> None:
    args = render.build_parser().parse_args([str(tmp_path / "score.txt"), "-o", "out", "--asymmetric-limits"])
    assert any(w.startswith("--asymmetric-limits has no effect without --limits-from") for w in
               render.options_in_vain(args))


def test_render_control_name_joint_works_in_batteur_physics(capsys: pytest.CaptureFixture[str]) -> None:
    """``--control joint`` is render's name for joint_pd (``render.CONTROL_MODES``); the node refused it."""
    assert render.CONTROL_MODES["joint"] == "joint_pd"
    assert _physics_settings(["--control", "joint"], capsys)["control"] == "joint_pd"
    assert _physics_settings(["--control", "joint_spd"], capsys)["control"] == "joint_spd"
