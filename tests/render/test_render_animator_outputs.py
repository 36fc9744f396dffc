"""An animator's render outputs (a walkthrough of 7 Dec): every output imported at frame 0 lines up, the video with
``--wav-from score`` carries the WAV it says it does, a file of the user's in the output folder is never replaced
without ``--overwrite``, the planner's reasons for flagged notes reach the terminal, and ``--kit`` reaches a text
score's kit object ids."""

from __future__ import annotations

import argparse
import json
import math
import shutil
import subprocess
from pathlib import Path
from typing import Any

import pytest
import soundfile as sf

from batteur import render
from common.kit import load_kit
from common.score.events import ScoreError

ROOT = Path(__file__).resolve().parents[2]
SCORE = ROOT / "tests" / "graphics" / "tiny_score.txt"
FPS = 10.0
MINE = "my cleaned-up take\n"

needs_ffmpeg = pytest.mark.skipif(shutil.which("ffmpeg") is None, reason="needs ffmpeg (apt-get install ffmpeg)")


@pytest.mark.slow  # a render with a video: about 20 s on a loaded core
@needs_ffmpeg
def test_with_wav_from_score_the_bvh_and_the_video_follow_the_trimmed_wav(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Until 7 Dec the default BVH started at the first pose (1.5 s ahead of the trimmed WAV, nothing said) and the
    video muxed the uncut WAV (1.5 s longer than performance.wav, its frames on the uncut WAV's clock)."""
    out = tmp_path / "out"
    assert render.main([str(SCORE), "-o", str(out), "--quiet", "--wav-from", "score", "--video",
                        "--video-size", "160x90", "--video-fps", f"{FPS:g}"]) == 0
    report = json.loads((out / "report.json").read_text())
    offset = report["score_offset_s"]
    assert report["bvh"]["sync"] == "wav" and report["bvh"]["wav_time_s"] == 0.0
    assert report["bvh"]["start_s"] == pytest.approx(offset, abs=1e-6)  # frame 0: score time 0
    said = capsys.readouterr().out
    assert (f"wrote {out / 'performance.bvh'} ({report['bvh']['frames']} frames at 60 Hz; frame 0 is "
            "performance.wav's time 0 (score time 0): imported at frame 0 the two line up)") in said, said

    wav = sf.info(str(out / "performance.wav"))
    assert wav.duration == pytest.approx(report["duration_s"], abs=1e-6)
    entry = report["video"]
    assert entry["frames"] == math.ceil(wav.duration * FPS - 1e-9)  # as long as the trimmed WAV
    assert entry["start_s"] == pytest.approx(offset, abs=1e-6)  # frame 0 shows score time 0, as the WAV's sample 0
    decoded = subprocess.run(["ffmpeg", "-v", "error", "-i", str(out / "performance.mp4"), "-map", "0:a", "-ac", "1",
                              "-ar", str(wav.samplerate), "-f", "s16le", "pipe:1"],
                             capture_output=True, check=True).stdout
    muxed_s = len(decoded) / 2 / wav.samplerate
    assert muxed_s == pytest.approx(wav.duration, abs=0.05), (muxed_s, wav.duration)  # the WAV written, not uncut


def test_a_users_file_is_refused_before_anything_is_simulated(tmp_path: Path,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    """``mkdir userdir; echo "my cleaned-up take" > userdir/performance.bvh; batteur render fill16.mid -o userdir``
    replaced the file until 7 Dec: refused now (exit 1), nothing written, the file named."""
    folder = tmp_path / "userdir"
    folder.mkdir()
    (folder / "performance.bvh").write_text(MINE)
    (folder / "notes.txt").write_text("other files are no render's business")
    assert render.main([str(SCORE), "-o", str(folder), "--quiet", "--gltf"]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"batteur render: error: -o: {folder / 'performance.bvh'} is not a file an earlier render "
                          "wrote there"), err
    assert "give --overwrite" in err
    assert sorted(p.name for p in folder.iterdir()) == ["notes.txt", "performance.bvh"]
    assert (folder / "performance.bvh").read_text() == MINE


def test_overwrite_replaces_them_and_a_renders_own_folder_needs_no_option(tmp_path: Path) -> None:
    folder = tmp_path / "userdir"
    folder.mkdir()
    (folder / "performance.bvh").write_text(MINE)
    assert render.main([str(SCORE), "-o", str(folder), "--quiet", "--overwrite"]) == 0
    assert (folder / "performance.bvh").read_text().startswith("HIERARCHY")
    # the folder is a render's now: rendering into it again replaces its files without the option
    render.check_outputs(folder, render.score_outputs(render.RenderOptions(video=True, gltf=True)))


def test_every_file_a_render_writes_is_checked() -> None:
    assert render.score_outputs(render.RenderOptions()) == ["performance.wav", "impacts.csv", "performance.bvh",
                                                            "report.json"]
    assert render.score_outputs(render.RenderOptions(video=True, gltf=True))[-2:] == ["performance.mp4",
                                                                                     "performance.glb"]


def test_a_report_json_of_the_users_lists_no_render_files(tmp_path: Path) -> None:
    """A report.json is a render's only with its ``scene``: the user's own (here a dict naming nothing) made every
    output name count as an earlier render's until 7 Dec, and their performance.wav was replaced."""
    (tmp_path / "report.json").write_text(json.dumps({"notes": "mine"}))
    (tmp_path / "performance.wav").write_bytes(b"RIFF")
    assert render.earlier_outputs(tmp_path) == set()
    with pytest.raises(render.RenderError) as refused:
        render.check_outputs(tmp_path, render.SCORE_OUTPUTS)
    assert str(refused.value).startswith(f"-o: {tmp_path / 'performance.wav'}, {tmp_path / 'report.json'} are not "
                                         "files an earlier render wrote there")
    render.check_outputs(tmp_path, render.SCORE_OUTPUTS, overwrite=True)  # --overwrite: replaced


def test_the_strike_scene_refuses_a_users_file_and_rerenders_its_own_folder(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "strikes"
    folder.mkdir()
    (folder / "impacts.csv").write_text(MINE)
    assert render.main(["--strikes", "0.1:2", "-o", str(folder), "--quiet"]) == 1
    assert f"-o: {folder / 'impacts.csv'} is not a file an earlier render wrote there" in capsys.readouterr().err
    assert sorted(p.name for p in folder.iterdir()) == ["impacts.csv"]
    (folder / "impacts.csv").unlink()
    assert render.main(["--strikes", "0.1:2", "-o", str(folder), "--quiet"]) == 0
    assert render.main(["--strikes", "0.1:2", "-o", str(folder), "--quiet"]) == 0  # its own folder: no option


def _report(issues: list[dict[str, Any]]) -> dict[str, Any]:
    return {"duration_s": 3.0, "score_time_0_wav_s": 1.55, "wav_from": "render", "impacts": 15, "notes": 21,
            "planner_issues": sum(i["note_index"] is not None for i in issues), "issues": issues,
            "unknown_notes": 0, "duplicates": 0, "real_time_factor": 1.0}


def _issue(reason: str, action: str, index: int | None = 1) -> dict[str, Any]:
    return {"note_index": index, "time_s": 0.1, "event": "SNARE", "reason": reason, "action": action, "detail": ""}


def test_the_planners_reasons_are_printed(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    """``batteur render fill203.mid --tempo-scale 10`` said ``8 flagged by the planner`` and no more until 7 Dec:
    the reasons were in report.json alone."""
    issues = ([_issue("too_fast", "merged")] * 4 + [_issue("too_fast", "dropped")] * 2
              + [_issue("too_fast", "played_anyway")] * 2 + [_issue("unknown_note", "dropped", None)])
    monkeypatch.setattr(render, "render_score", lambda *args, **kwargs: _report(issues))
    opts = argparse.Namespace(score=SCORE, output=tmp_path, quiet=True, overwrite=False, kit=None, grip=None,
                              nuance=None)
    monkeypatch.setattr(render, "options_from", lambda args: render.RenderOptions())
    assert render._main_score(opts, "batteur render") == 0
    lines = capsys.readouterr().out.splitlines()
    at = next(k for k, line in enumerate(lines) if "8 flagged by the planner" in line)
    assert lines[at + 1] == ("the planner's flags: too_fast 8 (4 merged, 2 dropped, 2 played anyway); each in "
                             "report.json's issues")


def test_the_planners_reasons_each_counted() -> None:
    issues = [_issue("unreachable", "moved_to_other_hand"), _issue("too_fast", "merged"),
              _issue("unreachable", "dropped"), _issue("unreachable", "dropped"), _issue("duplicate", "merged", None)]
    assert render.planner_flags_line(_report(issues)) == (
        "the planner's flags: unreachable 3 (2 dropped, 1 moved to other hand); too_fast 1 (1 merged); each in "
        "report.json's issues")
    assert render.planner_flags_line(_report([_issue("unknown_note", "dropped", None)])) is None  # the reader's


def test_kits_option_reaches_a_text_scores_kit_object_ids(tmp_path: Path) -> None:
    """Since c6f810b a text score names kit objects by id, looked up in its ``kit`` line's kit (else the default):
    ``batteur render --kit double_pedal`` of a score without the line refused ``crash2`` until 7 Dec."""
    score = tmp_path / "second_crash.txt"
    score.write_text("tempo 100\nSN |x...|\ncrash2 |..x.|\n", encoding="utf-8")
    kit = load_kit("double_pedal", warn=False)
    read, _, _ = render.prepare(score, kit, render.RenderOptions(kit="double_pedal"))
    assert len(read.events) == 2
    with pytest.raises(ScoreError, match="crash2"):  # the default kit has no second crash: its ids are listed
        render.read_scaled(score, render.RenderOptions())
