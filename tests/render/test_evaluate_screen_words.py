"""What ``batteur evaluate`` shows a researcher on screen: a legend under the table for its abbreviated columns
(``rho_s``, ``nodrum``, ``flag``, ``RTF`` were explained nowhere), a note the planner merged said in one sentence
(``too_fast (merged: ... merged into the SNARE at 0.600 s``), and ``--plots`` piano rolls whose top row's impacts are
not clipped at the border and whose legend covers no note."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from batteur import evaluate
from batteur.impact_log import write_impacts_csv
from common.kit import load_kit
from common.messages import Impact
from common.score.limbs import distribute
from common.score.text import read_score

OFFSET_S = 1.5
"""The render's score_offset_s: rig time = score time + it."""
FLAM = "tempo 120\nat 1.2 SN\nat 3.56 SN 0.4\nat 3.6 SN\nat 3.6 HH 0.6\nat 3 HH 0.6\nat 4.2 HH 0.6\n"
"""A flam's grace note 20 ms before its main stroke, both hands busy around it: the planner merges it."""


def _impact(k: int, t: float, instrument: str) -> Impact:
    return Impact(seq=k, time=OFFSET_S + t, instrument=instrument, zone="center", r=0.2, theta=0.0, velocity=2.0,
                  impulse=0.0, peak_force=0.0, duration=0.0, part="right_stick_tip")


def _render_dir(folder: Path) -> Path:
    """A render folder of :data:`FLAM` as `batteur render` writes one: every played note struck on time, report.json's
    issues the planner's (the same rows as render's)."""
    folder.mkdir()
    score_path = folder / "score.txt"
    score_path.write_text(FLAM)
    score = read_score(score_path)
    issues = distribute(score, load_kit("default"), "viterbi", "none").issues
    merged = {i.note_index for i in issues}
    impacts = [_impact(k, e.time, "snare" if e.event.value == "SNARE" else "hihat")
               for k, e in enumerate(score.events) if k not in merged]
    write_impacts_csv(sorted(impacts, key=lambda i: i.time), folder / "impacts.csv")
    rows = [{"note_index": i.note_index, "time_s": round(i.time, 6), "event": i.event.value if i.event else None,
             "reason": i.reason.value, "action": i.action.value, "detail": i.detail} for i in issues]
    report = {"scene": "drummer", "score": "flam.txt", "kit": "default", "issues": rows, "score_offset_s": OFFSET_S,
              "duration_s": 8.0, "wall_time_s": 40.0, "cpu_time_s": 40.0, "real_time_factor": 0.2}
    (folder / "report.json").write_text(json.dumps(report))
    return folder


def test_a_legend_under_the_table_says_every_column(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert evaluate.main([str(_render_dir(tmp_path / "r"))]) == 0
    head, _row, *rest = capsys.readouterr().out.splitlines()
    legend = evaluate.table_legend().splitlines()
    assert rest[:len(legend)] == legend  # right under the table
    said = " ".join(line.strip() for line in legend)
    columns = head.replace("|e| ms", "|e|").replace("bias ms", "bias").split()
    assert all(f"{column}: " in said or f"{column}, " in said for column in columns), (columns, said)
    assert "RTF: real-time factor, seconds of audio rendered per wall-clock second (below 1: slower than real time)" \
        in said
    assert all(len(line) <= evaluate.LEGEND_WIDTH for line in legend)


def test_a_merged_note_is_one_sentence_saying_merged_once(tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    assert evaluate.main([str(_render_dir(tmp_path / "r"))]) == 0
    [line] = [line for line in capsys.readouterr().out.splitlines() if " missed: " in line]
    assert line == ("  r (flam.txt): note 2 SNARE at 1.780 s missed: too_fast (merged: no hand can play it in time "
                    "(left hand: its previous stroke 1180 ms before, its next 20 ms after; right hand: its previous "
                    "stroke 280 ms before, its next 20 ms after; minTimeGap 70 ms, rebound minimum 30 ms), so it "
                    "sounds as one stroke with the left hand's SNARE at 1.800 s)"), line
    assert line.count("merged") == 1


@pytest.mark.parametrize("rows", [1, 4])
def test_the_piano_rolls_markers_lie_inside_it_and_its_legend_outside(rows: int) -> None:
    """Crosses 0.15 of a row above the top row's notes were cut at the axes' border (a kick-only file's every
    impact), and the legend in the upper right covered the notes there."""
    import matplotlib.pyplot as plt

    names = ["crash", "hihat", "kick", "snare"][:rows]
    notes = [evaluate.NoteRef(k, 0.25 * k, names[k % rows], 0.8) for k in range(4 * 8)]
    hits = [evaluate.Hit(n.time + 0.001, n.instrument, 2.0) for n in notes[:-1]]  # the last note missed
    hits.append(evaluate.Hit(notes[-1].time + 0.5, notes[-1].instrument, 2.0))  # at the right end, spurious
    result = evaluate.evaluate_performance("r (f.mid)", notes, hits)
    fig = evaluate.pianoroll_figure(result)
    try:
        fig.canvas.draw()
        ax = fig.axes[0]
        box = ax.get_window_extent()
        for collection in ax.collections:
            radius_px = math.sqrt(collection.get_sizes()[0]) / 2 * fig.dpi / 72
            for x, y in ax.transData.transform(collection.get_offsets()):
                assert box.y0 <= y - radius_px and y + radius_px <= box.y1, (collection.get_label(), y, box)
                assert box.x0 <= x - radius_px and x + radius_px <= box.x1, (collection.get_label(), x, box)
        legend = ax.get_legend().get_window_extent()
        assert legend.x0 >= box.x1, (legend, box)  # beside the axes, over no note
        assert fig.bbox.x0 <= legend.x0 and legend.x1 <= fig.bbox.x1 and fig.bbox.y0 <= legend.y0  # and in the PNG
        assert len(ax.get_legend().get_texts()) == 4  # played, missed, matched, spurious
    finally:
        plt.close(fig)
