"""``batteur render --bvh-units m|cm``: performance.bvh in metres (the default, Blender's unit) or centimetres (Maya's
and MotionBuilder's, where a metre file comes in 100 times too small)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from batteur import render
from common.gesture.bvh import read_bvh

ROOT = Path(__file__).resolve().parents[2]
SCORE = ROOT / "tests" / "graphics" / "tiny_score.txt"


def test_bvh_units_cm_writes_centimetres(tmp_path: Path) -> None:
    """Offsets and the root's positions are in centimetres: the pelvis 52 cm over the floor (0.52 in metres), the
    abdomen 23.7 cm above it, a stick's End Site 26.95 cm along it; report.json says the unit."""
    out = tmp_path / "out"
    assert render.main([str(SCORE), "-o", str(out), "--quiet", "--bvh-units", "cm"]) == 0
    text = (out / "performance.bvh").read_text()
    bvh = read_bvh(out / "performance.bvh")
    names = [j.name for j in bvh.joints]
    assert bvh.joints[names.index("abdomen")].offset[1] == pytest.approx(23.7, abs=0.1)  # y up
    first = [float(v) for v in text.split("Frame Time:")[1].splitlines()[1].split()]
    assert first[1] == pytest.approx(52.0, abs=0.5)  # the pelvis' height, Yposition
    tip = bvh.joints[names.index("right_stick")].end_site
    assert tip is not None and float(np.linalg.norm(tip)) == pytest.approx(26.95, abs=1e-3)
    assert json.loads((out / "report.json").read_text())["bvh"]["units"] == "cm"


def test_bvh_units_default_and_refusals(capsys: pytest.CaptureFixture[str]) -> None:
    parser = render.build_parser()
    assert render.options_from(parser.parse_args(["s.txt", "-o", "o"])).bvh_units == "m"
    assert render.options_from(parser.parse_args(["s.txt", "-o", "o", "--bvh-units", "cm"])).bvh_units == "cm"
    with pytest.raises(SystemExit) as exit_:
        parser.parse_args(["s.txt", "-o", "o", "--bvh-units", "mm"])
    assert exit_.value.code == 2 and "invalid choice: 'mm'" in capsys.readouterr().err
    args = parser.parse_args(["--strikes", "0.5:2", "-o", "o", "--bvh-units", "cm"])
    assert "--bvh-units has no effect with --strikes (the strike scene has no drummer)" in render.options_in_vain(args)


def test_the_library_writer_takes_the_unit_too(tmp_path: Path) -> None:
    """``render.write_outputs`` (the BVH of poses kept in memory, ``write_rest``'s; a render without a BVH rate)
    wrote metres whatever the unit: it takes ``units`` as the streamed writer does, metres by default. Offsets,
    End Sites and positions are 100 times the metre file's in centimetres; the angles are the same."""
    from services.graphics.figure import synthetic_performance

    poses = synthetic_performance(duration=0.5, rate_hz=60.0)[0]
    files = {}
    for units in ("m", "cm"):
        out = tmp_path / units
        render.write_outputs(out, np.zeros(480), 48000, [], {"scene": "drummer"}, poses=poses, bvh_rate_hz=60.0,
                             units=units)
        files[units] = read_bvh(out / "performance.bvh")
    render.write_outputs(tmp_path / "default", np.zeros(480), 48000, [], {"scene": "drummer"}, poses=poses,
                         bvh_rate_hz=60.0)
    assert (tmp_path / "default" / "performance.bvh").read_bytes() == (tmp_path / "m" / "performance.bvh").read_bytes()
    metres, centimetres = files["m"], files["cm"]
    assert [j.name for j in centimetres.joints] == [j.name for j in metres.joints]
    assert np.abs(metres.joints[1].offset).max() > 0.01  # a real offset, in metres
    for m, cm in zip(metres.joints, centimetres.joints, strict=True):
        assert cm.offset == pytest.approx(100 * m.offset, abs=1e-4)
        assert (cm.end_site is None) == (m.end_site is None)
        if m.end_site is not None:
            assert cm.end_site == pytest.approx(100 * m.end_site, abs=1e-4)
    positions = [k for k, c in enumerate(metres.joints[0].channels) if c.endswith("position")]
    assert len(positions) == 3 and metres.motion.shape == centimetres.motion.shape
    assert centimetres.motion[:, positions] == pytest.approx(100 * metres.motion[:, positions], abs=1e-4)
    assert centimetres.motion[:, 3:] == pytest.approx(metres.motion[:, 3:], abs=1e-4)  # the joints' angles
