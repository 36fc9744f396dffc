"""The lengths of a render's outputs agree with performance.wav's, and the render's refusals of the command line
are one line.

performance.wav holds whole blocks of the sound (256 samples), up to 5.3 ms short of the timeline simulated:
report.json's ``duration_s`` is the WAV's length, the glTF's last key is at or before the WAV's end, and with
``--bvh-sync wav`` the BVH (frame 0 at the WAV's time 0) ends where the WAV does, frame for frame with the glTF
(until 7 Dec the report and the glTF went to the timeline's end, past the WAV's, and the BVH 50 ms further, to
the last pose).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pygltflib
import pytest
import soundfile as sf

from batteur import render
from services.graphics.export import write_bvh
from services.graphics.export.bvh import BvhStream
from services.graphics.figure import synthetic_performance

ROOT = Path(__file__).resolve().parents[2]
SCORE = ROOT / "tests" / "graphics" / "tiny_score.txt"


@pytest.fixture(scope="module")
def rendered(tiny_gltf_render: Path) -> Path:
    """``SCORE`` rendered with ``--gltf`` (and the BVH on the WAV's clock, the default): tests/conftest.py's one
    render, read only."""
    return tiny_gltf_render


def bvh_frame_count(path: Path) -> int:
    """The ``Frames:`` of a BVH file's header, checked against its motion rows."""
    text = path.read_text()
    header = re.search(r"^Frames:\s*(\d+)\s*\nFrame Time:.*\n", text, re.M)
    assert header is not None
    rows = [row for row in text[header.end():].split("\n") if row.strip()]
    assert len(rows) == int(header.group(1))
    return len(rows)


def gltf_key_times(path: Path) -> np.ndarray:
    """The animation's key times, seconds (its first sampler's input)."""
    gltf = pygltflib.GLTF2().load(str(path))
    assert gltf is not None
    accessor = gltf.accessors[gltf.animations[0].samplers[0].input]
    view = gltf.bufferViews[accessor.bufferView]
    data = gltf.binary_blob()[view.byteOffset:view.byteOffset + view.byteLength]
    return np.frombuffer(data, dtype=np.float32)[:accessor.count]


def test_report_duration_is_the_wavs_length(rendered: Path) -> None:
    report = json.loads((rendered / "report.json").read_text())
    info = sf.info(str(rendered / "performance.wav"))
    assert info.frames % 256 == 0  # whole blocks: the case where the timeline and the WAV differ
    assert report["duration_s"] == pytest.approx(info.frames / info.samplerate, abs=1e-6)


def test_gltf_and_wav_synced_bvh_end_at_the_wavs_end(rendered: Path) -> None:
    """Frames k / rate of the WAV's clock up to its end: the glTF's keys and the BVH's frames are the same ones."""
    report = json.loads((rendered / "report.json").read_text())
    info = sf.info(str(rendered / "performance.wav"))
    wav_s = info.frames / info.samplerate
    rate = report["bvh"]["rate_hz"]
    frames = int(np.floor(wav_s * rate + 1e-9)) + 1  # frame 0 at the WAV's time 0, the last at or before its end
    keys = gltf_key_times(rendered / "performance.glb")
    assert len(keys) == report["gltf"]["frames"] == frames
    assert keys[-1] <= wav_s + 1e-6 and keys[-1] > wav_s - 1 / rate
    assert bvh_frame_count(rendered / "performance.bvh") == report["bvh"]["frames"] == frames


def test_a_bvh_stream_ends_where_it_is_told(tmp_path: Path) -> None:
    """``finish(end=)``: frames made past ``end`` are left out (poses went on after it), and a stream whose poses
    stop before ``end`` holds the last one up to it; the same bytes as :func:`write_bvh` given that end."""
    sequence = synthetic_performance(duration=2.0, rate_hz=60.0)[0]
    first, last = float(sequence.times[0]), float(sequence.times[-1])
    for end in (last - 0.1, last + 0.1):
        stream = BvhStream(tmp_path / "streamed.bvh", 60.0, chunk_frames=16, start=first - 0.05)
        stream.restart(list(sequence.names))
        for t, frame in zip(sequence.times, sequence.values, strict=True):
            stream.add(float(t), frame)
        frames = stream.finish(end=end)
        info = write_bvh(sequence, tmp_path / "whole.bvh", rate_hz=60.0, start=first - 0.05, end=end)
        assert frames == info.frames == int(np.floor((end - first + 0.05) * 60.0 + 1e-9)) + 1
        assert (tmp_path / "streamed.bvh").read_bytes() == (tmp_path / "whole.bvh").read_bytes()
        assert not (tmp_path / "streamed.bvh.motion").exists()


@pytest.mark.parametrize(("argv", "message"), [
    (["--strikes", "0.25:3", "--gltf"], "--gltf exports a SCORE's performance (the strike scene has no body to "
     "export)"),
    (["--strikes", "0.25:3", "--video"], "--video renders a SCORE (the strike scene has no body to draw)"),
    ([], "give a SCORE, or --strikes for the strike scene"),
    ([str(SCORE), "--strikes", "0.25:3"], "give either a SCORE or --strikes, not both"),
])
def test_options_that_exclude_each_other_are_one_line(argv: list[str], message: str, tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    """Exit status 2 and one line, as for a value out of range (until 7 Dec argparse's 16-line usage came first)."""
    assert render.main([*argv, "-o", str(tmp_path / "out")]) == 2
    captured = capsys.readouterr()
    assert captured.err == f"batteur render: error: {message}\n" and captured.out == ""
    assert not (tmp_path / "out").exists()


def test_the_strike_scenes_duration_is_its_wavs_length(tmp_path: Path) -> None:
    out = tmp_path / "strikes"
    assert render.main(["--strikes", "0.1:3", "-o", str(out), "--quiet", "--latency", "0.03"]) == 0
    info = sf.info(str(out / "performance.wav"))
    assert info.frames % 256 == 0 and info.frames / info.samplerate != 0.1 + 0.03 + 1.0  # whole blocks: shorter
    report = json.loads((out / "report.json").read_text())
    assert report["duration_s"] == pytest.approx(info.frames / info.samplerate, abs=1e-6)
