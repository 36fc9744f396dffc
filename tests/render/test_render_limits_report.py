"""``batteur render --limits-from CLIP``: report.json says which joints' limits have which formulation (Euler box
and quaternion ellipsoid, or the box alone), and the render says which ellipsoids the playing posture dropped (it
said nothing: one clip of standing motion left most joints with a grown box alone)."""

from __future__ import annotations

import json
import logging
from pathlib import Path

import pytest

from batteur import render

SCORE = "tempo 120\nmeter 4/4\nSN |x...|\n"


@pytest.mark.parametrize("asymmetric", [False, True])
def test_report_json_says_each_joints_limit_formulation(tmp_path: Path, caplog: pytest.LogCaptureFixture,
                                                        asymmetric: bool) -> None:
    """The clips' limits are mirror-symmetric (``+symmetric`` where a box changed) unless ``--asymmetric-limits``;
    ``physics.joint_limits_symmetric`` says which."""
    caplog.set_level(logging.WARNING, logger="batteur.physics")
    score = tmp_path / "snare.txt"
    score.write_text(SCORE, encoding="utf-8")
    out = tmp_path / "out"
    extra = ["--asymmetric-limits"] if asymmetric else []
    assert render.main([str(score), "-o", str(out), "--quiet", "--limits-from", "punch", *extra]) == 0
    report = json.loads((out / "report.json").read_text(encoding="utf-8"))
    assert report["physics"]["joint_limits_symmetric"] is not asymmetric
    limits = report["physics"]["joint_limits"]
    assert len(limits) == 19
    assert limits["right_shoulder"]["formulation"] == "euler"  # the seated posture is outside the punch's
    assert limits["right_shoulder"]["source"].endswith("+posture")
    assert limits["right_ankle"] == {"formulation": "euler+quaternion",
                                     "source": "mocap" if asymmetric else "mocap+symmetric", "dofs": ["mocap"] * 3}
    assert limits["seat"] == {"formulation": "euler", "source": "anatomical", "dofs": ["anatomical"] * 3}
    said = [r.getMessage() for r in caplog.records if r.getMessage().startswith("joint limits from punch: ")]
    assert len(said) == 1 and "right_shoulder" in said[0]


def test_a_segmented_render_reports_them_too(tmp_path: Path, capfd: pytest.CaptureFixture[str],
                                             caplog: pytest.LogCaptureFixture) -> None:
    """``--jobs 2``: each segment's drummer is built in a worker process; its limits reach report.json alike, and
    the workers' warning about them is said once and kept in report.json's warnings (until 8 Dec each worker
    printed it and report.json's warnings were empty)."""
    score = tmp_path / "snare.txt"
    score.write_text(SCORE, encoding="utf-8")
    out = tmp_path / "out"
    assert render.main([str(score), "-o", str(out), "--quiet", "--limits-from", "punch", "--jobs", "2",
                        "--segment", "1"]) == 0
    report = json.loads((out / "report.json").read_text(encoding="utf-8"))
    assert report["physics"]["segments"]["jobs"] == 2
    kept = [w for w in report["warnings"] if w.startswith("joint limits from punch: ")]
    assert len(kept) == 1 and "right_shoulder" in kept[0]
    said = [r.getMessage() for r in caplog.records if r.getMessage().startswith("joint limits from punch: ")]
    assert len(said) == 1  # by the parent, which prints it (to stderr) when logging has no handler
    assert "joint limits from punch: " not in capfd.readouterr().err  # not by each worker
    assert "segments" in report["physics"]
    limits = report["physics"]["joint_limits"]
    assert limits["right_shoulder"]["formulation"] == "euler" and limits["right_ankle"]["source"] == "mocap+symmetric"
    assert report["physics"]["joint_limits_symmetric"] is True
