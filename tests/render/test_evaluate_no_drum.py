"""``batteur evaluate`` on a file whose notes are mostly pitches with no drum: they were read and never played, yet
its table said F = 1.000 over the few that were (a walkthrough's 13 of 16 notes). They are listed as missed
(``no_drum_for_pitch``), counted in the ``nodrum`` column and the JSON's ``no_drum_notes``, said in a line under the
table, and left out of F, P and R, which judge the drummer on the notes it was given (docs/evaluation.md)."""

from __future__ import annotations

import json
from pathlib import Path

import mido
import pytest

from batteur import evaluate
from batteur.impact_log import write_impacts_csv
from common.messages import Impact

OFFSET_S = 1.5
"""The render's score_offset_s: rig time = score time + it."""


def _render_dir(folder: Path) -> Path:
    """A render folder of a MIDI file with two snares (score times 0 and 0.5 s) and three notes of pitches no drum
    has (0, 12, 127), both snares struck on time."""
    folder.mkdir()
    track = mido.MidiTrack()
    for pitch, delta in ((38, 0), (0, 0), (12, 240), (38, 240), (127, 0)):
        track.append(mido.Message("note_on", channel=9, note=pitch, velocity=100, time=delta))
    mido.MidiFile(tracks=[track], ticks_per_beat=480).save(folder / "score.mid")
    impacts = [Impact(seq=k, time=OFFSET_S + t, instrument="snare", zone="centre", r=0.2, theta=0.0, velocity=3.0,
                      impulse=0.0, peak_force=0.0, duration=0.0, part="left_stick_tip")
               for k, t in enumerate((0.0, 0.5))]
    write_impacts_csv(impacts, folder / "impacts.csv")
    report = {"scene": "drummer", "score": "lowhigh.mid", "kit": "default", "issues": [], "score_offset_s": OFFSET_S,
              "duration_s": 4.0, "wall_time_s": 3.0, "cpu_time_s": 3.0, "real_time_factor": 1.3}
    (folder / "report.json").write_text(json.dumps(report))
    return folder


def test_notes_with_no_drum_are_missed_apart_not_in_the_figures(tmp_path: Path) -> None:
    result = evaluate.evaluate_render_dir(tmp_path / "r" / "score.mid", _render_dir(tmp_path / "r"))
    assert (result.notes, result.f_measure["25ms"], result.no_drum_notes) == (2, 1.0, 3)
    missed = [(f.index, f.event, f.reason, f.source) for f in result.missed]
    assert sorted(missed, key=str) == sorted([(None, f"pitch {p}", "no_drum_for_pitch", "score") for p in (0, 12, 127)],
                                             key=str)
    assert result.missed_by_reason == {"no_drum_for_pitch": 3}
    summary = result.summary()
    assert summary["no_drum_notes"] == 3 and summary["missed"][0]["index"] is None
    assert evaluate.aggregate([result, result])["no_drum_notes"] == 6


def test_the_table_and_a_line_under_it_say_them(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = _render_dir(tmp_path / "r")
    assert evaluate.main([str(folder)]) == 0
    head, row, *rest = capsys.readouterr().out.splitlines()
    end = head.index("nodrum") + len("nodrum")  # right-aligned under its name
    assert row[:end].endswith(" 3"), (head, row)
    rest = rest[len(evaluate.table_legend().splitlines()):]  # the columns' legend, then the lines of each file
    assert rest[0].endswith("3 notes of the file not played: no drum for their pitch (nodrum; F, P and R count the 2 "
                            "the drummer was given)"), rest
    assert any(line.endswith("a note of pitch 127 at 0.500 s missed: no_drum_for_pitch (channel 10: no drum event "
                             "type for this pitch)") for line in rest), rest
    data = json.loads(_json(folder, capsys))
    assert data["files"][0]["no_drum_notes"] == 3 and data["aggregate"]["no_drum_notes"] == 3


def _json(folder: Path, capsys: pytest.CaptureFixture[str]) -> str:
    assert evaluate.main([str(folder), "--json"]) == 0
    return capsys.readouterr().out
