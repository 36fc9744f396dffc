"""Bad and unusual input to ``batteur render`` and ``batteur evaluate``: one line naming the problem, exit status
2 (130 after Ctrl-C), no traceback, nothing partial; most checks run before any simulation."""

from __future__ import annotations

import json
import logging
import shutil
from pathlib import Path
from typing import Any

import mido
import numpy as np
import pytest

from batteur import evaluate, render
from batteur.impact_log import COLUMNS
from common.gesture.plan import Nuance

HERE = Path(__file__).parent
SCORE = HERE / "short_groove.txt"
TINY = "tempo 120\nmeter 4/4\nSN |x.x.|\n"
"""One bar, two snare notes."""


def _midi(path: Path, channel: int, note: int) -> Path:
    track = mido.MidiTrack([mido.Message("note_on", channel=channel, note=note, velocity=100, time=0),
                            mido.Message("note_on", channel=channel, note=note, velocity=0, time=240)])
    mido.MidiFile(tracks=[track]).save(path)
    return path


def _fake_render(folder: Path, score_text: str = TINY, **report: Any) -> Path:
    """A render directory as `batteur render` writes one (no impacts), its report overridden by ``report``."""
    folder.mkdir(parents=True)
    (folder / "score.txt").write_text(score_text)
    (folder / "impacts.csv").write_text(",".join(COLUMNS) + "\n")
    base = {"scene": "drummer", "score": "tiny.txt", "kit": "default", "grip": "german", "nuance": "tenuto",
            "tempo_scale": 1.0, "control": "cartesian", "calibration": None, "issues": [], "score_offset_s": 1.5,
            "duration_s": 4.0, "wall_time_s": 3.0, "cpu_time_s": 3.0, "real_time_factor": 1.3}
    (folder / "report.json").write_text(json.dumps({**base, **report}))
    return folder


def _one_line_error(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err.strip()
    assert "Traceback" not in err
    lines = err.splitlines()
    assert len(lines) == 1, err
    return lines[0]


def test_ctrl_c_during_a_render_exits_130_without_traceback_or_output(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    def interrupted(*args: Any, **kwargs: Any) -> Any:
        raise KeyboardInterrupt

    monkeypatch.setattr(render, "run_score", interrupted)
    out = tmp_path / "out"
    assert render.main([str(SCORE), "-o", str(out), "--quiet"]) == 130
    assert "interrupted" in _one_line_error(capsys)
    assert not out.exists()
    monkeypatch.setattr(render, "render_score", interrupted)
    assert evaluate.main([str(SCORE), "--renders", str(out), "--quiet"]) == 130
    assert "interrupted" in _one_line_error(capsys)
    assert not out.exists()


def test_options_are_checked_before_simulating(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    def simulated(*args: Any, **kwargs: Any) -> Any:
        raise AssertionError("simulated before the options were checked")

    monkeypatch.setattr(render, "run_score", simulated)
    monkeypatch.setattr("batteur.segments.run_segmented", simulated)
    out = tmp_path / "out"
    for args, says in ((["--latency", "5", "--jobs", "2"], "--latency 5: 0 to 2 s"),
                       (["--latency", "-1"], "--latency -1: 0 to 2 s"),
                       (["--control-rate", "nan"], "--control-rate nan: must be a finite number, 50 to 1000 Hz"),
                       (["--tempo-scale", "1e-9"], "--tempo-scale 1e-09: 0.1 to 10"),  # 373 GiB of head samples
                       (["--tempo-scale", "nan"], "--tempo-scale nan"),
                       (["--jobs", "2", "--segment", "inf"], "--segment inf: a length of at least 1 s"),  # was silent
                       (["--jobs", "2", "--segment", "0"], "--segment 0: a length of at least 1 s"),
                       (["--jobs", "2", "--segment", "nan"], "--segment nan")):
        assert render.main([str(SCORE), "-o", str(out), "--quiet", *args]) == 2, args
        assert says in _one_line_error(capsys), args
    assert not out.exists()


def test_a_segmented_render_given_up_stops_its_running_segments(tmp_path: Path,
                                                               caplog: pytest.LogCaptureFixture) -> None:
    from batteur.segments import run_segmented
    from common.kit import load_kit

    score = tmp_path / "rock.txt"
    score.write_text("tempo 100\nmeter 4/4\n" + "\n\n".join(["HH |x.x.x.x.|\nSN |....X...|\nBD |x.......|"] * 6))
    kit = load_kit("default")
    opts = render.RenderOptions(jobs=2, segment_s=4.0)
    prepared = render.prepare(score, kit, opts)

    def ctrl_c_once_simulating(t: float, total: float) -> None:
        if t > 0:  # the segments are being simulated (each 4 s and a 3 s lead-in, a third one queued)
            raise KeyboardInterrupt

    with caplog.at_level(logging.INFO, logger="batteur.render"), pytest.raises(KeyboardInterrupt):
        run_segmented(*prepared, kit, opts, 2, on_progress=ctrl_c_once_simulating, segment_s=4.0)
    # the workers stop at their next check instead of playing their segments and the queued one to the end
    ended = [r.getMessage() for r in caplog.records if r.name == "batteur.render"]
    assert any("given up at rig time" in line for line in ended), ended
    assert not any("played to its end" in line for line in ended), ended


def test_a_score_without_drum_events_says_why(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    unknown = _midi(tmp_path / "unknown.mid", channel=9, note=20)
    assert render.main([str(unknown), "-o", str(tmp_path / "out"), "--quiet"]) == 1  # a file it cannot use
    err = _one_line_error(capsys)
    assert "no drum events to play" in err and "pitch 20" in err
    assert not (tmp_path / "out").exists()


def test_a_midi_file_without_drum_channel_is_played_with_a_warning(tmp_path: Path,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    melodic = _midi(tmp_path / "melodic.mid", channel=0, note=38)  # a snare pitch on channel 1
    out = tmp_path / "out"
    assert render.main([str(melodic), "-o", str(out), "--quiet"]) == 0
    warning = "no notes on a drum channel; reading channels [1] as drums"
    assert warning in capsys.readouterr().err
    assert any(warning in w for w in json.loads((out / "report.json").read_text())["warnings"])


@pytest.mark.parametrize(("report", "says"), [
    ({"issues": "none"}, "issues must be a list"),
    ({"issues": [[1, 2]]}, "issue 0 is not a planner issue"),
    ({"issues": [{"note_index": 0}]}, "issue 0 has no 'time_s'"),
    ({"kit": 5}, "kit must be a kit name"),
    ({"score_offset_s": None}, "no score_offset_s"),
    ({"score_offset_s": float("nan")}, "score_offset_s must be a finite number"),  # every note would be missed
    ({"tempo_scale": "fast"}, "tempo_scale must be a finite number"),
    ({"tempo_scale": 0}, "tempo_scale must be positive"),
    ({"real_time_factor": "x"}, "real_time_factor must be a finite number"),
    ({"duration_s": [1]}, "duration_s must be a finite number"),
])
def test_a_damaged_report_is_named_not_a_traceback(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                   report: dict[str, Any], says: str) -> None:
    folder = _fake_render(tmp_path / "render", **report)
    assert evaluate.main([str(folder), "--quiet"]) == 1  # a file it cannot use
    err = _one_line_error(capsys)
    assert "report.json" in err and says in err


def test_a_binary_impacts_file_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = _fake_render(tmp_path / "render")
    (folder / "impacts.csv").write_bytes(b"\xff\xfe\x00garbage")
    assert evaluate.main([str(folder), "--quiet"]) == 1  # a file it cannot use
    assert "impacts.csv: not UTF-8 text" in _one_line_error(capsys)


def test_a_bad_base_calibration_is_refused_before_fitting(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = _fake_render(tmp_path / "render")
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    fitted = tmp_path / "fitted.json"
    assert evaluate.main([str(folder), "--fit-calibration", str(fitted), "--calibration", str(bad), "--quiet"]) == 1
    assert "bad.json: not a calibration file" in _one_line_error(capsys)
    assert not fitted.exists()
    assert evaluate.main([str(folder), "--fit-calibration", str(fitted), "--kit", "nokit", "--quiet"]) == 1
    assert "nokit" in _one_line_error(capsys)
    assert not fitted.exists()


def test_reuse_takes_only_a_render_of_the_same_score_and_options(tmp_path: Path) -> None:
    score = tmp_path / "tiny.txt"
    score.write_text(TINY)
    opts = render.RenderOptions()
    assert evaluate.reusable(_fake_render(tmp_path / "same"), score, opts)
    # another score of the same name (another folder, an earlier version) would be judged against these notes
    assert not evaluate.reusable(_fake_render(tmp_path / "other", TINY.replace("x.x.", "x...")), score, opts)
    assert not evaluate.reusable(_fake_render(tmp_path / "faster", tempo_scale=2.0), score, opts)
    assert not evaluate.reusable(_fake_render(tmp_path / "joint", control="joint"), score, opts)
    assert not evaluate.reusable(tmp_path / "missing", score, opts)
    assert evaluate.reusable(tmp_path / "same", score, render.RenderOptions(nuance=Nuance.TENUTO))


def test_two_scores_of_one_name_cannot_share_a_render_folder(tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    for folder in ("a", "b"):
        (tmp_path / folder).mkdir()
        shutil.copyfile(SCORE, tmp_path / folder / "groove.txt")
    renders = tmp_path / "renders"
    args = [str(tmp_path / "a" / "groove.txt"), str(tmp_path / "b" / "groove.txt"), "--renders", str(renders)]
    assert evaluate.main([*args, "--quiet"]) == 2
    err = _one_line_error(capsys)
    assert "would both render into" in err and "groove" in err
    assert not renders.exists()


def test_missing_figures_keep_the_table_aligned(tmp_path: Path) -> None:
    result = evaluate.evaluate_render_dir(tmp_path / "render" / "score.txt", _fake_render(tmp_path / "render"))
    table = evaluate.format_table([(result.name, result.summary()), ("ALL", evaluate.aggregate([result]))])
    lengths = {len(line) for line in table.splitlines()}
    assert len(lengths) == 1, table


def test_a_render_into_an_earlier_render_leaves_none_of_its_files(tmp_path: Path) -> None:
    out = tmp_path / "out"
    earlier = _fake_render(out, score="old.mid", video={"file": "performance.mp4"})
    (earlier / "score.mid").write_bytes(b"MThd")
    (earlier / "performance.mp4").write_bytes(b"old video")
    (earlier / "mine.txt").write_text("not the render's")
    score = tmp_path / "new.txt"
    score.write_text(TINY)
    render.write_outputs(out, np.zeros(480), 48000, [], {"scene": "drummer", "score": str(score)}, score=score)
    # `batteur evaluate out` must not judge the new impacts against the old score, nor the video be taken for them
    assert sorted(p.name for p in out.iterdir()) == ["impacts.csv", "mine.txt", "performance.wav", "report.json",
                                                    "score.txt"]


def test_a_render_folder_with_an_earlier_score_copy_is_judged_against_its_own(tmp_path: Path) -> None:
    folder = _fake_render(tmp_path / "render", score="new.txt")
    (folder / "score.mid").write_bytes(b"MThd")  # left by a render of a MIDI file before this fix
    assert evaluate.render_dir_score(folder) == folder / "score.txt"


def test_motion_capture_options_are_read_before_simulating(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    """--limits-from and --skeleton-bvh name files the drummer is built from: a missing or unusable one is
    refused, naming the option, before the score is planned or anything simulated."""
    def simulated(*args: Any, **kwargs: Any) -> Any:
        raise AssertionError("simulated before the motion capture files were read")

    monkeypatch.setattr(render, "run_score", simulated)
    legs_only = tmp_path / "legs.bvh"
    legs_only.write_text("HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 3 Zrotation Xrotation Yrotation\n"
                         " End Site\n {\n  OFFSET 0 10 0\n }\n}\nMOTION\nFrames: 2\nFrame Time: 0.03\n0 0 0\n0 0 0\n",
                         encoding="utf-8")
    # shoulders 36 times as far apart as the hips: ten times a performer's in centimetres, and no other unit
    # (millimetres: hips 1 cm apart) makes them a performer's
    giant = tmp_path / "giant.bvh"
    arms = "".join(f" JOINT {side}{part}\n {{\n  OFFSET {x} {y} 0\n  CHANNELS 3 Zrotation Xrotation Yrotation\n"
                   f"  End Site\n  {{\n   OFFSET 0 {y or -280} 0\n  }}\n }}\n" for part, y, sides in (
                       ("Arm", 0, (("Left", 180), ("Right", -180))), ("UpLeg", -40, (("Left", 5), ("Right", -5))))
                   for side, x in sides)
    giant.write_text("HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 3 Zrotation Xrotation Yrotation\n" + arms
                     + "}\nMOTION\nFrames: 2\nFrame Time: 0.03\n" + "0 0 0 0 0 0 0 0 0 0 0 0 0 0 0\n" * 2,
                     encoding="utf-8")
    out = tmp_path / "out"
    for args, says in ((["--limits-from", str(tmp_path / "none.bvh")], "--limits-from: no BVH file"),
                       (["--limits-from", "moonwalk"], "--limits-from: no clip 'moonwalk'"),
                       (["--limits-from", str(legs_only)], "cannot tell which way is up"),
                       (["--skeleton-bvh", str(legs_only)], "--skeleton-bvh"),
                       (["--skeleton-bvh", str(giant)], "shoulder_width length 3.6 m is implausible")):
        assert render.main([str(SCORE), "-o", str(out), "--quiet", *args]) == 1, args  # a file it cannot use
        assert says in _one_line_error(capsys), args
        assert not out.exists()
