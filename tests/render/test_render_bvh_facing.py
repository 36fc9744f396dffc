"""``batteur render --bvh-facing +z|-z``: which way the drummer faces in performance.bvh.

+z (the default since 8 Dec) is the glTF's way and CMU's and Mixamo's clips'; -z keeps the files made before, which
faced the other way from the glTF of the same render (tests/render/test_render_gltf.py checks the two agree now).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from batteur import cli, render
from common.gesture.bvh import forward_kinematics, read_bvh
from services.graphics.export.bvh import BVH_FACINGS

ROOT = Path(__file__).resolve().parents[2]
SCORE = ROOT / "tests" / "graphics" / "tiny_score.txt"
HALF_TURN = np.diag([-1.0, 1.0, -1.0])
"""The half turn about y between the two facings (x and z negated)."""


def test_minus_z_renders_the_same_motion_half_a_turn_round(tiny_gltf_render: Path, tmp_path: Path) -> None:
    """``--bvh-facing -z`` (as two words: argparse alone took "-z" for an option) writes the render's motion facing
    -z: every joint where the default (+z) file has it turned half a turn about y, the same header's channels, and
    report.json's ``bvh.facing`` says which; the WAV and impacts are the same."""
    out = tmp_path / "out"
    assert cli.main(["render", str(SCORE), "-o", str(out), "--quiet", "--bvh-facing", "-z"]) == 0
    assert json.loads((out / "report.json").read_text())["bvh"]["facing"] == "-z"
    assert json.loads((tiny_gltf_render / "report.json").read_text())["bvh"]["facing"] == "+z"
    minus, plus = read_bvh(out / "performance.bvh"), read_bvh(tiny_gltf_render / "performance.bvh")
    assert [j.channels for j in minus.joints] == [j.channels for j in plus.joints]
    assert minus.motion.shape == plus.motion.shape
    a, b = forward_kinematics(minus), forward_kinematics(plus)
    assert set(a) == set(b)
    for joint in a:
        assert np.abs(a[joint] - b[joint] @ HALF_TURN).max() < 1e-5, joint  # metres
    assert a["right_stick_end"][:, 2].max() < 0.0 < b["right_stick_end"][:, 2].min()  # in front of him: -z, +z
    for name in ("performance.wav", "impacts.csv"):
        assert (out / name).read_bytes() == (tiny_gltf_render / name).read_bytes(), name


def test_the_option_its_default_and_refusals(capsys: pytest.CaptureFixture[str]) -> None:
    parser = render.build_parser()
    assert render.options_from(parser.parse_args(["s.txt", "-o", "o"])).bvh_facing == "+z"
    assert render.RenderOptions().bvh_facing == "+z"
    for given in (["--bvh-facing=-z"], render.facing_joined(["--bvh-facing", "-z"])):
        assert render.options_from(parser.parse_args(["s.txt", "-o", "o", *given])).bvh_facing == "-z"
    assert render.facing_joined(["s.txt", "--bvh-facing", "+z", "-o", "o"]) == ["s.txt", "--bvh-facing=+z", "-o", "o"]
    assert render.BVH_FACINGS == BVH_FACINGS
    with pytest.raises(SystemExit) as exit_:
        render.main(["s.txt", "-o", "o", "--bvh-facing", "z"])
    assert exit_.value.code == 2 and "invalid choice: 'z'" in capsys.readouterr().err
    args = parser.parse_args(["--strikes", "0.5:2", "-o", "o", "--bvh-facing=-z"])
    assert "--bvh-facing has no effect with --strikes (the strike scene has no drummer)" in render.options_in_vain(args)


def test_the_library_writer_takes_the_facing_too(tmp_path: Path) -> None:
    """``render.write_outputs`` (the BVH of poses kept in memory) faces as told, +z by default."""
    from services.graphics.figure import synthetic_performance

    poses = synthetic_performance(duration=0.5, rate_hz=60.0)[0]
    render.write_outputs(tmp_path / "default", np.zeros(480), 48000, [], {"scene": "drummer"}, poses=poses,
                         bvh_rate_hz=60.0)
    placed = {}
    for facing in BVH_FACINGS:
        render.write_outputs(tmp_path / facing, np.zeros(480), 48000, [], {"scene": "drummer"}, poses=poses,
                             bvh_rate_hz=60.0, facing=facing)
        placed[facing] = forward_kinematics(read_bvh(tmp_path / facing / "performance.bvh"))
    default = (tmp_path / "default" / "performance.bvh").read_bytes()
    assert default == (tmp_path / "+z" / "performance.bvh").read_bytes()
    assert len(placed["+z"]) > 20
    for joint, at in placed["+z"].items():
        assert np.abs(placed["-z"][joint] - at @ HALF_TURN).max() < 1e-5, joint
