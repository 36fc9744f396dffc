"""``batteur render SCORE`` end to end (planner -> physics drummer -> interaction -> sound) and its evaluation.

The score is two bars of a rock beat (hi-hat with accents on every other stroke,
snare, kick: both hands and the kick foot), so CI stays short. Thresholds: the
issue's goals (F-measure at 25 ms >= 0.99, median |timing error| <= 3 ms, 95th
percentile <= 10 ms), and louder written notes struck faster; see
docs/evaluation.md ("Test thresholds"). bench/evaluate_groove.py measures the
same goals on the Groove MIDI validation split.
"""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from batteur import evaluate, render

HERE = Path(__file__).parent
SCORE = HERE / "short_groove.txt"
MIDI = HERE.parent / "data" / "groove_drummer6_s3_1_rock_90_beat_4-4.mid"


@pytest.fixture(scope="module")
def rendered(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("render") / "out"
    assert render.main([str(SCORE), "-o", str(out), "--quiet"]) == 0
    return out


def test_render_writes_wav_impacts_bvh_and_report(rendered: Path) -> None:
    report = json.loads((rendered / "report.json").read_text())
    assert report["scene"] == "drummer" and report["control"] == "cartesian"
    assert report["notes"] == 13 and report["planned_strokes"] == 13
    audio, sr = sf.read(rendered / "performance.wav")
    assert sr == report["sample_rate_hz"] == 48000
    assert abs(len(audio) / sr - report["duration_s"]) < 0.02
    assert np.abs(audio).max() > 0.01  # the contacts were heard
    with (rendered / "impacts.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == report["impacts"] > 0
    assert {r["instrument"] for r in rows} >= {"snare", "hihat"}
    for r in rows:  # each impact completed by its end (sent with the first contact, they were 0 there)
        assert float(r["impulse"]) > 0 and float(r["peak_force"]) > 0 and 0 < float(r["duration"]) <= 0.05
    times = [float(r["time"]) for r in rows]
    assert times == sorted(times)
    bvh = (rendered / "performance.bvh").read_text()
    assert bvh.startswith("HIERARCHY") and "MOTION" in bvh
    frames = int(bvh.split("Frames:")[1].split()[0])
    assert float(bvh.split("Frame Time:")[1].split()[0]) == pytest.approx(1 / 60, abs=1e-8)  # physics' pose rate
    assert abs(frames / 60.0 - report["duration_s"]) < 0.05  # over the whole render
    assert (rendered / "score.txt").read_text() == SCORE.read_text()  # the directory evaluates on its own
    assert not [p for p in rendered.iterdir() if p.name.startswith(".render-")]  # no staging left


def test_a_damaged_render_directory_is_named_with_what_is_wrong(rendered: Path, tmp_path: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    copy = tmp_path / "copy"
    shutil.copytree(rendered, copy)
    report, impacts = (copy / "report.json").read_text(), (copy / "impacts.csv").read_text()
    for name, damaged, says in (
            ("impacts.csv", impacts + "garbage,row\n", "impacts.csv: line "),
            ("impacts.csv", None, "no impacts.csv"),
            ("report.json", "{not json", "report.json: not a render report"),
            ("report.json", "[1, 2]", "not a JSON object"),
            ("report.json", '{"scene": "drummer"}', "no score_offset_s")):
        (copy / "report.json").write_text(report)
        (copy / "impacts.csv").write_text(impacts)
        if damaged is None:
            (copy / name).unlink()
        else:
            (copy / name).write_text(damaged)
        assert evaluate.main([str(copy), "--quiet"]) == 1, name  # a file it cannot use
        err = capsys.readouterr().err
        assert says in err and "Traceback" not in err


def test_evaluation_of_the_render(rendered: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert evaluate.main([str(rendered), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    result = data["files"][0]
    assert result["notes"] == 13
    # no note silently lost: every note is matched or missed with a reason
    assert result["matched"]["25ms"] + len(result["missed"]) == result["notes"]
    assert all(m["reason"] and m["detail"] for m in result["missed"])
    # the accuracy goals: the right object at the right time
    assert result["f_measure"]["25ms"] >= 0.99
    assert result["timing_ms"]["median_abs"] <= 3.0 and result["timing_ms"]["p95_abs"] <= 10.0
    assert data["aggregate"]["real_time_factor"] > 0


def test_accented_hihat_strokes_are_struck_faster(rendered: Path) -> None:
    with (rendered / "impacts.csv").open() as handle:
        hats = [r for r in csv.DictReader(handle) if r["instrument"] == "hihat"]
    assert len(hats) == 8  # one contact per hi-hat note, alternately accented (X) and not (x)
    accented = [float(r["velocity"]) for r in hats[0::2]]
    plain = [float(r["velocity"]) for r in hats[1::2]]
    assert min(accented) > max(plain), (accented, plain)


def test_corrupted_midi_fails_clearly_and_writes_nothing(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "broken.mid"
    bad.write_bytes(MIDI.read_bytes()[:200])
    out = tmp_path / "out"
    assert render.main([str(bad), "-o", str(out), "--quiet"]) == 1
    err = capsys.readouterr().err
    assert "broken.mid" in err and "truncated" in err.lower()
    assert not out.exists()


def test_a_control_rate_of_zero_is_refused_not_taken_as_the_default(tmp_path: Path,
                                                                      capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    assert render.main([str(MIDI), "-o", str(out), "--control-rate", "0", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "--control-rate 0: 50 to 1000 Hz" in err and "control_rate_hz" not in err
    assert not out.exists()


def test_an_output_that_cannot_be_a_directory_is_refused_before_rendering(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    a_file = tmp_path / "notes.txt"
    a_file.write_text("mine")
    assert render.main([str(MIDI), "-o", str(a_file), "--quiet"]) == 1  # an output it cannot use
    assert "exists and is not a directory" in capsys.readouterr().err
    assert a_file.read_text() == "mine"
    assert render.main([str(MIDI), "-o", str(a_file / "out"), "--quiet"]) == 1
    assert "is a file, not a directory" in capsys.readouterr().err
    assert render.main(["--strikes", "0.25:2", "-o", str(a_file), "--quiet"]) == 1
    assert "exists and is not a directory" in capsys.readouterr().err
    for option, value, says in (("--plots", a_file / "plots", "is a file"), ("--renders", a_file, "not a directory"),
                                ("--fit-calibration", tmp_path / "missing" / "c.json", "does not exist"),
                                ("--fit-calibration", tmp_path, "is a directory")):
        assert evaluate.main([str(MIDI), option, str(value), "--quiet"]) == 1
        err = capsys.readouterr().err
        assert option in err and says in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt"]
    assert evaluate.main([str(tmp_path), "--quiet"]) == 1  # a folder, but not a render
    assert "not a render directory" in capsys.readouterr().err


def test_bad_text_score_names_the_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.txt"
    bad.write_text("tempo 100\nZZ |x...|\n")
    out = tmp_path / "out"
    assert render.main([str(bad), "-o", str(out), "--quiet"]) == 1
    assert "line 2" in capsys.readouterr().err
    assert not out.exists()


def test_failed_write_leaves_nothing_partial(tmp_path: Path) -> None:
    out = tmp_path / "new"
    with pytest.raises(Exception):  # noqa: B017 - soundfile's own error type
        render.write_outputs(out, np.zeros((4, 4, 4)), 48000, [], {"scene": "drummer"})
    assert not out.exists()
    kept = tmp_path / "kept"
    kept.mkdir()
    (kept / "report.json").write_text("old")
    with pytest.raises(Exception):  # noqa: B017
        render.write_outputs(kept, np.zeros((4, 4, 4)), 48000, [], {"scene": "drummer"})
    assert [p.name for p in kept.iterdir()] == ["report.json"]
    assert (kept / "report.json").read_text() == "old"


def test_tempo_scale_divides_every_time() -> None:
    from common.score.text import read_score

    score = read_score(SCORE)
    fast = render.scale_tempo(score, 2.0)
    assert [e.time for e in fast.events] == pytest.approx([e.time / 2 for e in score.events])
    for bad in (0.0, -1.0, float("nan"), float("inf")):  # inf would put every note at 0 s
        with pytest.raises(ValueError, match="positive finite"):
            render.scale_tempo(score, bad)


def test_evaluate_lists_the_nuances_it_knows(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as refused:
        evaluate.main([str(SCORE), "--nuance", "bogus"])
    assert refused.value.code == 2 and "staccato" in capsys.readouterr().err


def test_a_fitted_calibration_says_what_it_holds(rendered: Path, tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    """The message named the offsets' keys as if each were an instrument ("2 timing offsets" for a snare alone:
    the snare's and its SNARE sound's)."""
    fitted = tmp_path / "cal.json"
    assert evaluate.main([str(rendered), "--fit-calibration", str(fitted), "--quiet"]) == 0
    timing = json.loads(fitted.read_text())["timing_s"]
    objects = sorted(key for key in timing if "/" not in key)
    line = [x for x in capsys.readouterr().err.splitlines() if x.startswith(f"wrote {fitted}")][0]
    assert f"timing offsets for {len(objects)} kit objects and {len(timing) - len(objects)} of their sounds" in line
