"""Offline video: MP4 duration, frame rate, and audio onsets in sync with the impacts (and the picture)."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
import soundfile

from common.messages import Impact
from services.graphics.figure import SyntheticDrummer
from services.graphics.video import camera_eye, find_ffmpeg, render_video

from .conftest import needs_ffmpeg, project

RATE = 48_000
FPS = 30.0
W, H = 320, 180


def click_track(impacts: list[Impact], duration: float, delay: float) -> np.ndarray:
    """A WAV standing in for the rendered sound: a 15 ms noise burst at every strike time + ``delay``."""
    rng = np.random.default_rng(7)
    audio = np.zeros(int(duration * RATE))
    burst = rng.uniform(-0.8, 0.8, int(0.015 * RATE)) * np.exp(-np.arange(int(0.015 * RATE)) / 200.0)
    for imp in impacts:
        start = int(round((imp.time + delay) * RATE))
        audio[start : start + len(burst)] += burst[: len(audio) - start]
    return np.clip(audio, -1, 1)


def onsets(signal: np.ndarray, rate: int, threshold: float = 0.05, refractory: float = 0.05) -> list[float]:
    """Times (seconds) where |signal| first exceeds ``threshold`` after ``refractory`` seconds of quiet."""
    above = np.flatnonzero(np.abs(signal) > threshold)
    out: list[float] = []
    last = -np.inf
    for i in above:
        if i / rate - last > refractory:
            out.append(i / rate)
        last = i / rate
    return out


def ffprobe(path: Path) -> dict[str, object]:
    ffprobe_bin = str(Path(find_ffmpeg()).with_name("ffprobe"))
    result = subprocess.run([ffprobe_bin, "-v", "error", "-count_frames", "-show_streams", "-show_format", "-of",
                             "json", str(path)], capture_output=True, text=True, check=True)
    data: dict[str, object] = json.loads(result.stdout)
    return data


@needs_ffmpeg
@pytest.mark.parametrize("latency", [0.0, 0.1])
def test_mp4_duration_rate_and_audio_in_sync(tmp_path: Path, latency: float) -> None:
    drummer = SyntheticDrummer(duration=2.0)
    sequence, impacts = drummer.sequence(60.0), drummer.impacts()
    wav = tmp_path / "performance.wav"
    soundfile.write(wav, click_track(impacts, 2.0, latency), RATE)
    info = render_video(sequence, impacts, wav, tmp_path, fps=FPS, width=W, height=H, latency=latency)
    assert info.path == tmp_path / "performance.mp4" and info.path.is_file()

    probe = ffprobe(info.path)
    streams = {s["codec_type"]: s for s in probe["streams"]}  # type: ignore[attr-defined]
    video, audio = streams["video"], streams["audio"]
    assert video["r_frame_rate"] == "30/1"
    assert int(video["nb_read_frames"]) == 60
    assert (int(video["width"]), int(video["height"])) == (W, H)
    assert float(probe["format"]["duration"]) == pytest.approx(2.0, abs=1 / FPS)  # type: ignore[index]
    assert audio["codec_name"] == "aac"

    # the muxed audio's onsets fall on the strikes (+ the latency window) within one video frame
    decoded = subprocess.run([find_ffmpeg(), "-v", "error", "-i", str(info.path), "-map", "0:a", "-ac", "1", "-ar",
                              str(RATE), "-f", "f32le", "pipe:1"], capture_output=True, check=True).stdout
    found = onsets(np.frombuffer(decoded, dtype=np.float32), RATE)
    expected = sorted({round(i.time + latency, 6) for i in impacts})
    assert len(found) == len(expected)
    assert np.max(np.abs(np.array(found) - np.array(expected))) < 1 / FPS


@needs_ffmpeg
def test_picture_flashes_with_the_sound(tmp_path: Path) -> None:
    """The crash is struck once (at 0.5 s): its disc lights up in the frame where the audio onset is."""
    drummer = SyntheticDrummer(duration=1.2)
    sequence, impacts = drummer.sequence(60.0), drummer.impacts()
    latency = 0.1
    wav = tmp_path / "p.wav"
    soundfile.write(wav, click_track(impacts, 1.2, latency), RATE)
    camera = {"azimuth_deg": 0.0, "elevation_deg": 18.0, "distance": 3.0, "target": (0.0, 0.35, 0.75)}
    info = render_video(sequence, impacts, wav, tmp_path, fps=FPS, width=W, height=H, latency=latency, camera=camera)
    raw = subprocess.run([find_ffmpeg(), "-v", "error", "-i", str(info.path), "-f", "rawvideo", "-pix_fmt", "rgb24",
                          "pipe:1"], capture_output=True, check=True).stdout
    frames = np.frombuffer(raw, dtype=np.uint8).reshape(-1, H, W, 3).astype(float)
    crash = drummer.kit.object("crash")
    eye = camera_eye(0.0, 18.0, 3.0, (0.0, 0.35, 0.75))
    # a point on the crash's far side from the stick, so the stick never covers it
    x, y = project(np.asarray(crash.position) + np.array([-0.12, 0.0, 0.0]), eye, np.array([0.0, 0.35, 0.75]),
                   45.0, W, H)
    patch = frames[:, int(y) - 1 : int(y) + 2, int(x) - 1 : int(x) + 2].mean(axis=(1, 2))
    brightness = patch.sum(axis=1)
    strike_frame = int(np.ceil((0.5 + latency) * FPS - 1e-9))  # first frame at or after the sound of the strike
    before = brightness[strike_frame - 3 : strike_frame].max()
    assert brightness[strike_frame] > before + 60, brightness[strike_frame - 3 : strike_frame + 3]
    # not early either: the disc is unchanged in every frame before the one the strike is heard in
    assert np.ptp(brightness[:strike_frame]) < 10, brightness[:strike_frame]
