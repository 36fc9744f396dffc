"""``batteur compare``: a rushed or dragging beat says the statistic it is told by (its median); a render folder
or its impacts file given as the take points to its recording and to ``batteur evaluate``; the MIDI reader's
``--hihat-cc4`` notice is not said (compare matches open and closed hi-hat notes alike)."""

from __future__ import annotations

from pathlib import Path

import mido
import pytest

from batteur.compare import summary_lines
from tests.cli.test_compare import EXERCISE, START, report, run, write_take, written


@pytest.fixture
def exercise(tmp_path: Path) -> Path:
    path = tmp_path / "exercise.txt"
    path.write_text(EXERCISE, encoding="utf-8")
    return path


def test_a_beat_s_feel_and_its_number_are_one_statistic(exercise: Path, tmp_path: Path,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    """Two onsets 30 ms early and one 100 ms late: rushed by its median (-30 ms), its mean +13 ms (until 7 Dec
    "rushed, +13 ms on average")."""
    path = write_take(tmp_path / "take.mid", [(START + t, p, v) for t, p, v in written(exercise)])
    got = report([str(exercise), str(path)], capsys)
    got["beats_rushed_dragging"] = [{"bar": 2, "beat": 3, "last_beat": 3, "onsets": 3, "notes": 3,
                                     "mean_ms": 13.3, "median_ms": -30.0, "feel": "rushed"}]
    lines = summary_lines(got, "exercise.txt", "take.mid")
    assert "bar 2, beat 3: rushed, -30 ms median (3 notes)" in lines


@pytest.mark.parametrize("given", ["", "impacts.csv", "report.json"])
def test_a_render_given_as_the_take_points_to_its_recording_and_evaluate(
        given: str, exercise: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    render = tmp_path / "render"
    render.mkdir()
    for name in ("impacts.csv", "performance.wav", "report.json"):
        (render / name).write_text("x\n", encoding="utf-8")
    status, out, err = run([str(exercise), str(render / given) if given else str(render)], capsys)
    assert status == 1 and out == ""
    assert f"({render / 'performance.wav'})" in err and f"batteur evaluate {render}" in err
    assert "is a folder" not in err and "text file" not in err


def test_the_hihat_cc4_notice_is_not_said(exercise: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """An exercise (and a take) sending the pedal fully down (CC4 127) before open hi-hat notes: the reader's
    "would play closed with --hihat-cc4" is no matter to a comparison matching open and closed alike."""
    mid = mido.MidiFile(type=0, ticks_per_beat=1000)
    track = mido.MidiTrack()
    mid.tracks.append(track)
    track.append(mido.MetaMessage("set_tempo", tempo=500_000))
    track.append(mido.Message("control_change", channel=9, control=4, value=127, time=0))
    for k in range(8):
        track.append(mido.Message("note_on", channel=9, note=46, velocity=100, time=0 if k == 0 else 500))
        track.append(mido.Message("note_off", channel=9, note=46, velocity=0, time=500))
    path = tmp_path / "pedal.mid"
    mid.save(path)
    status, out, err = run([str(path), str(path)], capsys)
    assert status == 0 and "CC4" not in err and "CC4" not in out
    got = report([str(path), str(path)], capsys)
    assert got["played"] == 8 and not any("CC4" in w for w in got["warnings"])
