"""Where bar 1 is in performance.wav, for a DAW user (a walkthrough imported the WAV at bar 1 and found it 1.55 s
late, or 2.45 s early for a file opening with two empty bars): ``batteur render`` says where score time 0 (bar 1,
beat 1) falls in the WAV (printed and report.json's ``score_time_0_wav_s``), and ``--wav-from score`` writes the
WAV from score time 0 (the settle trimmed, or silence added before), refusing to cut a stroke struck before bar 1.
Its impacts.csv line counts the notes with no drum for their pitch apart from the planner's flags."""

from __future__ import annotations

import json
import os
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
import soundfile as sf

from batteur import render

SR = 48000


def _wav(path: Path, samples: np.ndarray) -> None:
    sf.write(path, samples, SR, subtype="PCM_24")


def _ints(path: Path) -> np.ndarray:
    return sf.read(path, dtype="int32")[0]


def test_score_time_0_is_its_rig_time_plus_the_latency_and_said_before_or_in_the_wav() -> None:
    assert render.score_time_0_wav_s(1.5, 0.05) == 1.55  # a score starting on beat 1: the lead-in and settle
    assert render.score_time_0_wav_s(-2.5, 0.05) == -2.45  # two empty bars at 120 bpm before the first note
    assert render.bar_one_line(1.55) == "score time 0 (bar 1, beat 1) is at 1.550 s in performance.wav"
    assert render.bar_one_line(-2.45) == "score time 0 (bar 1, beat 1) is 2.450 s before the start of performance.wav"


def test_shift_wav_trims_or_pads_keeping_every_sample(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    samples = rng.uniform(-0.5, 0.5, 3 * SR + 17)
    _wav(tmp_path / "a.wav", samples)
    original = _ints(tmp_path / "a.wav")
    _wav(tmp_path / "b.wav", samples)
    assert render.shift_wav(tmp_path / "a.wav", 74400) == len(original) - 74400  # 1.55 s trimmed
    assert np.array_equal(_ints(tmp_path / "a.wav"), original[74400:])
    assert render.shift_wav(tmp_path / "b.wav", -117600) == len(original) + 117600  # 2.45 s of silence added
    padded = _ints(tmp_path / "b.wav")
    assert np.array_equal(padded[117600:], original) and not padded[:117600].any()
    assert sf.info(str(tmp_path / "b.wav")).subtype == "PCM_24"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.wav", "b.wav"]  # no temporary file left


def test_first_sound_finds_the_first_sample_that_is_not_silent(tmp_path: Path) -> None:
    samples = np.zeros(SR)
    samples[70000 % SR] = 0.25
    _wav(tmp_path / "a.wav", samples)
    assert render.first_sound(tmp_path / "a.wav", SR) == 70000 % SR
    assert render.first_sound(tmp_path / "a.wav", 100) is None  # only silence among the first 100


def _impact(rig_s: float, instrument: str = "snare") -> Any:
    return SimpleNamespace(time=rig_s, instrument=instrument)


def test_a_stroke_before_bar_1_is_refused_a_first_note_a_little_early_is_trimmed_with_a_warning() -> None:
    offset = 1.5  # score time 0 at rig time 1.5 s, heard at 1.55 s: 74400 samples cut
    with pytest.raises(render.RenderError, match=r"1 impact struck before score time 0 .* would be cut.*0\.250 s"):
        render.check_wav_from_score([_impact(1.25), _impact(2.0)], offset, 74400, SR, 70000)
    warning = render.check_wav_from_score([_impact(1.499, "kick"), _impact(2.0)], offset, 74400, SR, 74400 - 160)
    assert warning is not None and "(kick) is struck 1.0 ms before score time 0" in warning
    assert "first 3.3 ms of its sound are cut" in warning
    assert render.check_wav_from_score([_impact(2.0)], offset, 74400, SR, 96000) is None  # only silence cut
    assert render.check_wav_from_score([_impact(2.0)], offset, 74400, SR, None) is None


def _cli(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], tmp_path: Path,
         **report: Any) -> list[str]:
    """render's lines for a render whose report is ``report`` (the render itself stood in for)."""
    base = {"duration_s": 5.296, "impacts": 3, "notes": 3, "planner_issues": 0, "unknown_notes": 0,
            "duplicates": 0, "issues": [], "wav_from": "render", "score_time_0_wav_s": 1.55, "score_beats": 16.0,
            "score_bars": 4, "real_time_factor": 1.0}
    monkeypatch.setattr(render, "render_score", lambda *args, **kwargs: {**base, **report})
    assert render.main([str(tmp_path / "x.mid"), "-o", str(tmp_path / "out"), "--quiet"]) == 0
    return capsys.readouterr().out.splitlines()


def test_render_says_where_bar_1_is_and_the_score_length(monkeypatch: pytest.MonkeyPatch,
                                                         capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    lines = _cli(monkeypatch, capsys, tmp_path, score_time_0_wav_s=-2.45)
    assert lines[0].endswith("performance.wav (5.3 s; the score: 4 bars (16 beats))"), lines
    assert lines[1].startswith("score time 0 (bar 1, beat 1) is 2.450 s before the start of performance.wav; "
                               "--wav-from score"), lines


def test_notes_with_no_drum_are_counted_apart_from_the_planners_flags(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    # the report's issues list them too (note_index null): the line said "13 flagged by the planner"
    issues = [{"note_index": None, "reason": "unknown_note"}] * 13
    lines = _cli(monkeypatch, capsys, tmp_path, issues=issues, unknown_notes=13)
    assert lines[2].endswith("(3 impacts for 3 notes, 0 flagged by the planner; 13 notes not played: no drum for "
                             "their pitch)"), lines


def test_one_impact_for_one_note_is_said_in_the_singular(monkeypatch: pytest.MonkeyPatch,
                                                         capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    lines = _cli(monkeypatch, capsys, tmp_path, impacts=1, notes=1)  # until 7 Dec "1 impacts for 1 notes"
    assert lines[2].endswith("(1 impact for 1 note, 0 flagged by the planner)"), lines


TEXT = "tempo 120\nmeter 4/4\nrest 4\nHH |x.x.|\nSN |..x.|\nBD |x...|\n"
"""A bar of rest, then a bar with three notes: the first note 2 s in, after the WAV's 1.5 s of settle and lead-in,
so bar 1 is 0.45 s before the start of the render's WAV."""


@pytest.fixture(scope="module")
def from_score(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("bar1")
    (folder / "score.txt").write_text(TEXT)
    (folder / "sp.yaml").write_text("instruments: {snare: {level: 0}}\n")
    out = folder / "out"
    here = Path.cwd()
    os.chdir(folder)  # --sound-params given relative to it
    try:
        assert render.main([str(folder / "score.txt"), "-o", str(out), "--quiet", "--wav-from", "score",
                            "--bvh-sync", "wav", "--sound-params", "sp.yaml"]) == 0
    finally:
        os.chdir(here)
    return out


def test_the_report_records_the_sound_params_file_absolute(from_score: Path) -> None:
    # until 7 Dec as typed ("sp.yaml"), which means nothing read from another folder
    report = json.loads((from_score / "report.json").read_text())
    assert report["sound_params"] == str((from_score.parent / "sp.yaml").resolve())


def test_wav_from_score_starts_the_wav_at_bar_1(from_score: Path) -> None:
    report = json.loads((from_score / "report.json").read_text())
    cut = round(report["score_offset_s"] + report["latency_s"], 6)
    assert cut == pytest.approx(-0.45)  # bar 1 before the render's start: silence added
    assert (report["wav_from"], report["score_time_0_wav_s"], report["wav_cut_s"]) == ("score", 0.0, cut)
    wav = _ints(from_score / "performance.wav")
    # duration_s is the written WAV's length, as without --wav-from (until 7 Dec: the uncut render's, 0.45 s less)
    assert len(wav) == round(report["duration_s"] * SR) == round(report["wav_duration_s"] * SR)
    first = int(np.flatnonzero(wav)[0]) / SR
    assert 2.0 - 0.01 < first < 2.0 + 0.01  # the first note, 2 s after bar 1 (its sound from ~3 ms before)
    assert report["bvh"]["wav_time_s"] == 0.0  # --bvh-sync wav: frame 0 at the WAV's time 0, bar 1
    impacts = (from_score / "impacts.csv").read_text().splitlines()
    first_impact = float(impacts[1].split(",")[1])  # impacts.csv keeps rig times
    assert first_impact - report["score_offset_s"] == pytest.approx(2.0, abs=0.01)


def test_wav_from_with_the_strike_scene_is_warned_of_as_doing_nothing() -> None:
    args = render.build_parser().parse_args(["--strikes", "0.25:3", "-o", "out", "--wav-from", "score"])
    assert "--wav-from has no effect with --strikes (the strike scene has no drummer)" in render.options_in_vain(args)
