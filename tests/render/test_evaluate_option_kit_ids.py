"""``batteur evaluate DIR`` on the render of a text score naming an object only the kit played has (``crash2`` with
``batteur render --kit double_pedal``): the render's copy of the score is read with that kit, as render read it.
Until 7 Dec it was read with its own kit line's (the default): "unknown instrument 'crash2'", nothing evaluated."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from batteur import evaluate
from batteur.impact_log import write_impacts_csv
from common.messages.events import Impact

OFFSET_S = 1.5
SCORE = "tempo 100\nSN |x...|\ncrash2 |..x.|\n"  # 100 bpm, a bar of 4 steps: snare at 0 s, crash2 at 1.2 s


def _impact(seq: int, t: float, instrument: str) -> Impact:
    return Impact(seq=seq, time=OFFSET_S + t, instrument=instrument, zone="edge", r=0.8, theta=0.0, velocity=3.0,
                  impulse=0.0, peak_force=0.0, duration=0.0, part="right_stick_tip")


def _render_dir(folder: Path) -> Path:
    """A render folder as ``batteur render s.txt --kit double_pedal`` writes one (its score's copy, no kit line)."""
    folder.mkdir(parents=True)
    (folder / "score.txt").write_text(SCORE)
    write_impacts_csv([_impact(0, 0.002, "snare"), _impact(1, 1.202, "crash2")], folder / "impacts.csv")
    report = {"scene": "drummer", "score": "s.txt", "kit": "double_pedal", "grip": "german", "nuance": "tenuto",
              "tempo_scale": 1.0, "control": "cartesian", "calibration": None, "issues": [], "score_offset_s": OFFSET_S,
              "duration_s": 2.0, "wall_time_s": 3.0, "cpu_time_s": 3.0, "real_time_factor": 1.5}
    (folder / "report.json").write_text(json.dumps(report))
    return folder


def test_a_render_of_kit_object_ids_only_its_kit_has_is_evaluated(tmp_path: Path) -> None:
    folder = _render_dir(tmp_path / "out")
    result = evaluate.evaluate_render_dir(folder / "score.txt", folder)
    assert result.notes == 2 and not result.missed and not result.spurious
    assert result.recall["25ms"] == 1.0


def test_the_command_evaluates_such_a_render(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = _render_dir(tmp_path / "out")
    assert evaluate.main([str(folder), "--json", "--quiet"]) == 0
    out = capsys.readouterr()
    assert "unknown instrument" not in out.err
    (result,) = json.loads(out.out)["files"]
    assert result["notes"] == 2 and result["missed"] == []
