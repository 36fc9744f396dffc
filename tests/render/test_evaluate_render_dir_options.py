"""`batteur evaluate DIR` reads a render made earlier: options that would change a render (--height, --tempo-scale,
--kit, ...) cannot apply to it. They were ignored in silence (the figures looked like those of the render asked
for); now a warning names them."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from batteur import evaluate
from batteur.impact_log import COLUMNS


def _render_dir(folder: Path) -> Path:
    """A render directory as `batteur render` writes one, with no impacts."""
    folder.mkdir(parents=True)
    (folder / "score.txt").write_text("tempo 120\nmeter 4/4\nSN |x.x.|\n")
    (folder / "impacts.csv").write_text(",".join(COLUMNS) + "\n")
    report = {"scene": "drummer", "score": "tiny.txt", "kit": "default", "grip": "german", "nuance": "tenuto",
              "tempo_scale": 1.0, "control": "cartesian", "calibration": None, "issues": [], "score_offset_s": 1.5,
              "duration_s": 4.0, "wall_time_s": 3.0, "cpu_time_s": 3.0, "real_time_factor": 1.3}
    (folder / "report.json").write_text(json.dumps(report))
    return folder


def _warnings(capsys: pytest.CaptureFixture[str]) -> list[str]:
    return [line for line in capsys.readouterr().err.splitlines() if "warning" in line]


def test_render_options_given_with_a_render_directory_are_named_as_unused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = _render_dir(tmp_path / "take1")
    assert evaluate.main([str(folder), "--height", "1.4", "--tempo-scale", "2", "--quiet"]) == 0
    assert _warnings(capsys) == [
        f"batteur evaluate: warning: {folder} is a render: --height and --tempo-scale do not apply to it (it was "
        "rendered with the options in its report.json)"]


def test_a_render_directory_alone_evaluates_without_a_warning(tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    assert evaluate.main([str(_render_dir(tmp_path / "take1")), "--list", "--json", "--quiet"]) == 0
    assert _warnings(capsys) == []


def test_the_kit_and_calibration_of_a_fit_are_not_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # --fit-calibration uses --kit and --calibration (the fit's kit and base) even for render directories
    folder = _render_dir(tmp_path / "take1")
    base = tmp_path / "base.json"
    base.write_text('{"timing_s": {}, "velocity": {}, "reference": null, "samples": {}}')
    assert evaluate.main([str(folder), "--kit", "left_handed", "--calibration", str(base), "--fit-calibration",
                          str(tmp_path / "fit.json"), "--quiet"]) == 0
    assert _warnings(capsys) == []
