"""``batteur render SCORE --video``: the physics drummer rendered to DIR/performance.mp4 with its sound in sync.

The score is four strokes (tests/graphics/tiny_score.txt, about 4 s of rig
time with the settle, lead-in and tail), rendered at 320x180 so the whole
render stays short.
"""

from __future__ import annotations

import json
import math
import subprocess
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from batteur import render
from services.graphics import video

from .conftest import needs_ffmpeg
from .test_video import ffprobe, onsets

SCORE = Path(__file__).with_name("tiny_score.txt")
FPS = 25.0
W, H = 320, 180


@needs_ffmpeg
def test_render_video_duration_rate_audio_and_report(tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert render.main([str(SCORE), "-o", str(out), "--quiet", "--video", "--video-size", f"{W}x{H}",
                        "--video-fps", f"{FPS:g}"]) == 0
    report = json.loads((out / "report.json").read_text())
    mp4 = out / "performance.mp4"
    assert mp4.is_file()
    frames = math.ceil(report["duration_s"] * FPS - 1e-9)  # the video lasts as long as the WAV, whole frames
    assert report["video"]["file"] == "performance.mp4"
    assert report["video"]["frames"] == frames and report["video"]["fps"] == FPS
    assert (report["video"]["width"], report["video"]["height"]) == (W, H)

    probe = ffprobe(mp4)
    streams = {s["codec_type"]: s for s in probe["streams"]}  # type: ignore[attr-defined]
    v, a = streams["video"], streams["audio"]
    assert v["r_frame_rate"] == "25/1" and int(v["nb_read_frames"]) == frames
    assert (int(v["width"]), int(v["height"])) == (W, H)
    assert float(probe["format"]["duration"]) == pytest.approx(report["duration_s"], abs=1 / FPS)  # type: ignore[index]
    assert a["codec_name"] == "aac" and int(a["sample_rate"]) == report["sample_rate_hz"]

    # the muxed sound is the WAV, in place: no shift between them (envelopes in 1 ms blocks, cross-correlated)
    wav, rate = sf.read(out / "performance.wav")
    decoded = subprocess.run([video.find_ffmpeg(), "-v", "error", "-i", str(mp4), "-map", "0:a", "-ac", "1", "-ar",
                              str(rate), "-f", "f32le", "pipe:1"], capture_output=True, check=True).stdout
    muxed = np.frombuffer(decoded, dtype=np.float32)
    block = rate // 1000
    n = min(len(wav), len(muxed)) // block
    env_wav = np.abs(wav[: n * block]).reshape(n, block).max(axis=1)
    env_mp4 = np.abs(muxed[: n * block]).reshape(n, block).max(axis=1)
    lags = np.arange(-200, 201)
    score = [float(np.dot(env_wav[200:-200], env_mp4[200 + k : n - 200 + k])) for k in lags]
    assert abs(int(lags[int(np.argmax(score))])) < 1000 / FPS  # milliseconds
    # and every strike is heard at its impact time + the latency window, as the picture shows it, within one
    # video frame (strikes closer than the onset detector's 50 ms refractory time are heard as one onset)
    times = sorted(float(r.split(",")[1]) for r in (out / "impacts.csv").read_text().splitlines()[1:])
    groups = [t for k, t in enumerate(times) if k == 0 or t - times[k - 1] > 0.05]
    assert len(groups) >= 2  # hi-hat + kick, then hi-hat + snare
    heard = onsets(muxed, rate, 0.02 * float(np.abs(muxed).max()))
    assert len(heard) == len(groups), (heard, groups)
    for onset, strike in zip(heard, groups, strict=True):
        assert onset == pytest.approx(strike + report["latency_s"], abs=1 / FPS)


def test_render_video_without_ffmpeg_fails_before_rendering(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    def missing() -> str:
        raise FileNotFoundError("ffmpeg not found: apt-get install ffmpeg (or pip install imageio-ffmpeg)")

    monkeypatch.setattr(video, "find_ffmpeg", missing)
    out = tmp_path / "out"
    assert render.main([str(SCORE), "-o", str(out), "--quiet", "--video"]) == 1  # the machine lacks it
    assert "ffmpeg not found" in capsys.readouterr().err
    assert not out.exists()  # nothing written, nothing simulated


def test_render_video_options_are_checked(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert render.main([str(SCORE), "-o", str(tmp_path / "a"), "--quiet", "--video", "--video-size", "321x180"]) == 2
    assert "even" in capsys.readouterr().err
    assert render.main(["--strikes", "0.2:3", "-o", str(tmp_path / "b"), "--video"]) == 2  # one line, no usage
    assert capsys.readouterr().err == ("batteur render: error: --video renders a SCORE (the strike scene has no body "
                                       "to draw)\n")
    with pytest.raises(SystemExit):
        render.main([str(SCORE), "-o", str(tmp_path / "c"), "--video-size", "big"])
    assert not (tmp_path / "a").exists()


def test_a_failing_encoder_leaves_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(video, "find_ffmpeg", lambda: "/bin/false")  # "ffmpeg" that exits at once with an error
    out = tmp_path / "out"
    assert render.main([str(SCORE), "-o", str(out), "--quiet", "--video", "--video-size", "64x36"]) == 1
    assert "--video: ffmpeg failed (exit status 1)" in capsys.readouterr().err
    assert not out.exists()  # the WAV, BVH and report were staged, not written
