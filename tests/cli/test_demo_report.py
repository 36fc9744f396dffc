"""``batteur demo``'s report.json names the score copy it leaves in its folder, not the temporary file the demo
was rendered from (deleted once the render is done)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from batteur import demo, evaluate


@pytest.mark.slow
def test_the_demo_report_names_the_score_beside_it(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "demo"
    assert demo.main(["-o", str(out), "--quiet"]) == 0
    report = json.loads((out / "report.json").read_text(encoding="utf-8"))
    score = Path(report["score"])
    assert score == out / "score.txt"
    assert score.read_text(encoding="utf-8") == demo.DEMO_GROOVE
    assert report["notes"] > 0 and report["impacts"] > 0  # the rest of the report is the render's
    assert sorted(p.name for p in out.iterdir()) == ["impacts.csv", "performance.bvh", "performance.wav",
                                                     "report.json", "score.txt"]
    capsys.readouterr()
    assert evaluate.main([str(out), "--json"]) == 0
    row = json.loads(capsys.readouterr().out)["files"][0]
    assert row["notes"] == report["notes"] and row["music_duration_s"] == report["music_duration_s"]
