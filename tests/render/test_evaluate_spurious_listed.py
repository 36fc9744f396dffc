"""``batteur evaluate`` lists each spurious impact as it lists each missed note: a walkthrough's render said ``spur 2``
and nothing more (a crash hit on the way to the ride). Under the table: its time, object, striker, velocity, the
nearest note on that object and, on another object, the note nearest in time; capped per file, the rest counted;
in the JSON, each file's ``spurious_impacts``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from batteur import evaluate
from batteur.impact_log import write_impacts_csv
from common.messages import Impact

OFFSET_S = 1.5
"""The render's score_offset_s: rig time = score time + it."""
SCORE = "tempo 120\nmeter 4/4\nCR |x...|\nRD |..x.|\n"
"""A crash at score time 0, a ride at 1.0 s."""


def _impact(k: int, t: float, instrument: str, part: str = "right_stick_tip", velocity: float = 2.5) -> Impact:
    return Impact(seq=k, time=OFFSET_S + t, instrument=instrument, zone="edge", r=0.8, theta=0.0, velocity=velocity,
                  impulse=0.0, peak_force=0.0, duration=0.0, part=part)


def _render_dir(folder: Path, extra: int = 1) -> Path:
    """A render folder of :data:`SCORE`, both notes struck on time, and ``extra`` crash hits on the way to the ride
    (0.95 s, then 1 ms apart)."""
    folder.mkdir()
    (folder / "score.txt").write_text(SCORE)
    impacts = [_impact(0, 0.0, "crash"), _impact(1, 1.0, "ride")]
    impacts += [_impact(2 + k, 0.95 + k * 0.001, "crash", velocity=1.25) for k in range(extra)]
    write_impacts_csv(sorted(impacts, key=lambda i: i.time), folder / "impacts.csv")
    report = {"scene": "drummer", "score": "groove.txt", "kit": "default", "issues": [], "score_offset_s": OFFSET_S,
              "duration_s": 4.0, "wall_time_s": 3.0, "cpu_time_s": 3.0, "real_time_factor": 1.3}
    (folder / "report.json").write_text(json.dumps(report))
    return folder


def test_each_spurious_impact_is_said_with_the_notes_near_it(tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    assert evaluate.main([str(_render_dir(tmp_path / "r"))]) == 0
    out = capsys.readouterr().out.splitlines()
    said = [line for line in out if "spurious" in line]
    assert said == ["  r (groove.txt): impact at 0.950 s on crash spurious: right_stick_tip 1.25 m/s, nearest note 0 "
                    "CRASH on crash at 0.000 s (+950.0 ms); nearest in time: note 1 RIDE on ride at 1.000 s "
                    "(-50.0 ms)"], out


def test_they_are_capped_and_in_the_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = _render_dir(tmp_path / "r", extra=evaluate.MAX_DETAIL_LINES + 3)
    assert evaluate.main([str(folder)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert len([line for line in out if " spurious: " in line]) == evaluate.MAX_DETAIL_LINES
    assert out[-1] == "  r (groove.txt): ... 3 more spurious impacts (see --json, --list)", out[-1]
    assert evaluate.main([str(folder), "--json"]) == 0
    (file,) = json.loads(capsys.readouterr().out)["files"]
    rows = file["spurious_impacts"]
    assert len(rows) == file["spurious"] == evaluate.MAX_DETAIL_LINES + 3
    assert rows[0]["instrument"] == "crash" and rows[0]["nearest_note"]["event"] == "CRASH"
    assert not any(row["matched"] for row in rows)
