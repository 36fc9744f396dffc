"""A small drummer's render of a kit with an instrument beyond its reach: the hand does not go there, so the notes
it reaches play (a bar of four snare notes and a far china at 1.40 m: 1 of 5 played before, the right stick held at
the edge of its reach hit the ride); evaluate lists the far note as missed, ``unreachable``."""

from __future__ import annotations

import json
from pathlib import Path

from batteur import evaluate, render
from common.kit import load_kit
from tests.far_kits import china_at

SCORE = "tempo 120\nmeter 4/4\nSN |x.x.x.x.|\nCH |....x...|\n"


def test_the_notes_in_reach_play_and_the_far_one_is_missed_as_unreachable(tmp_path: Path) -> None:
    kit_file, score = tmp_path / "edge.json", tmp_path / "china.txt"
    kit_file.write_text(china_at(load_kit("default"), 1.10).model_dump_json())  # 1.15 m from a 1.40 m shoulder
    score.write_text(SCORE)
    out = tmp_path / "out"
    assert render.main([str(score), "-o", str(out), "--quiet", "--kit", str(kit_file), "--height", "1.4"]) == 0
    report = json.loads((out / "report.json").read_text())
    assert report["physics"]["pulled_into_reach"] == {}  # no knot beyond the body's reach (was 134 of the right's)
    result = evaluate.evaluate_render_dir(evaluate.render_dir_score(out), out)
    assert result.matched["25ms"] == 4
    assert [(f.index, f.event, f.reason) for f in result.missed] == [(2, "CHINA", "unreachable")]
