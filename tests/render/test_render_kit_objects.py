"""A text score naming a kit's objects by id (``crash2``, ``floortom2``, ``ride2`` of the double pedal kit; the
score's ``kit`` line) renders them on those objects: impacts.csv shows each note struck on the object named, and
``batteur evaluate`` of the render, which expects each note on the object its event and pitch choose, matches every
note (tests/score/test_score_kit_objects.py for the reading). The row names were the event types only: a second
crash or a fourth tom could not be written in a text score."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from batteur import evaluate, render

SCORE = """kit double_pedal
tempo 100
CR        |x.......|
crash2    |....x...|
floortom2 |..x...x.|
BD        |x...x...|
at 1.5 ride2 0.8
"""
BEAT_S = 0.6


def test_objects_named_by_id_are_struck_and_judged_on_those_objects(tmp_path: Path,
                                                                    capsys: pytest.CaptureFixture[str]) -> None:
    score = tmp_path / "objects.txt"
    score.write_text(SCORE, encoding="utf-8")
    out = tmp_path / "out"
    assert render.main([str(score), "-o", str(out), "--quiet"]) == 0
    offset = json.loads((out / "report.json").read_text())["score_offset_s"]
    with (out / "impacts.csv").open() as handle:
        struck = sorted((round((float(r["time"]) - offset) / BEAT_S * 4) / 4, r["instrument"])
                        for r in csv.DictReader(handle) if r["instrument"] != "kick")
    assert struck == [(0.0, "crash"), (1.0, "floortom2"), (2.0, "crash2"), (3.0, "floortom2"), (5.5, "ride2")]
    capsys.readouterr()
    assert evaluate.main([str(out), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)["files"][0]
    assert result["notes"] == 7 and result["matched"]["25ms"] == 7 and not result["missed"]
