"""``batteur render --bvh-sync wav`` (the default since 7 Dec): performance.bvh's frame 0 at performance.wav's time
0, the first pose held until it comes, so the BVH and the WAV imported at frame 0 line up; ``--bvh-sync pose`` keeps
the file as it was before (frame 0 the first pose; report.json's ``bvh`` entry says where its frame 0 falls in the
WAV)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pygltflib
import pytest

from batteur import render
from services.graphics.export import write_bvh
from services.graphics.export.bvh import Y_UP, BvhStream
from services.graphics.figure import synthetic_performance
from services.graphics.sequence import PoseSequence

ROOT = Path(__file__).resolve().parents[2]
SCORE = ROOT / "tests" / "graphics" / "tiny_score.txt"


def _physics_like(seconds: float) -> PoseSequence:
    """Poses from rig time 0.5 s on the 1 ms grid at about 60 Hz, as physics sends them."""
    smooth = synthetic_performance(duration=seconds, rate_hz=240.0)[0]
    times = np.unique(np.round(np.arange(0.0, seconds, 1 / 60), 3)) + 0.5
    return PoseSequence(smooth.names, times, np.stack([smooth.sample(float(t - 0.5)) for t in times]))


def motion_rows(path: Path) -> np.ndarray:
    """A BVH file's motion rows, (frames, channels)."""
    text = path.read_text()
    rows = text[re.search(r"^Frame Time:.*$", text, re.M).end():].split("\n")  # type: ignore[union-attr]
    return np.array([[float(v) for v in row.split()] for row in rows if row.strip()])


def test_a_bvh_from_an_earlier_start_holds_the_first_pose_then_plays_on(tmp_path: Path) -> None:
    """Frame k at ``start + k / rate``: the frames before the first pose are it, and from it on the motion is the
    default file's (3 frames later: the start is 3 frames before the first pose); streamed, the same bytes."""
    sequence = _physics_like(2.0)
    start = float(sequence.times[0]) - 3 / 60
    write_bvh(sequence, tmp_path / "default.bvh", rate_hz=60.0)
    info = write_bvh(sequence, tmp_path / "synced.bvh", rate_hz=60.0, start=start)
    default, synced = motion_rows(tmp_path / "default.bvh"), motion_rows(tmp_path / "synced.bvh")
    assert info.frames == len(synced) == len(default) + 3
    assert np.all(synced[:4] == default[0])  # held: the first pose, 3 frames before it and at it
    assert np.allclose(synced[3:], default, atol=2e-6)
    stream = BvhStream(tmp_path / "streamed.bvh", 60.0, chunk_frames=16, start=start)
    stream.restart(list(sequence.names))
    for t, frame in zip(sequence.times, sequence.values, strict=True):
        stream.add(float(t), frame)
    assert stream.finish() == info.frames and stream.start_time == start
    assert (tmp_path / "streamed.bvh").read_bytes() == (tmp_path / "synced.bvh").read_bytes()


def _gltf_translation(path: Path, node_name: str) -> np.ndarray:
    gltf = pygltflib.GLTF2().load(str(path))
    assert gltf is not None
    node = [n.name for n in gltf.nodes].index(node_name)
    animation = gltf.animations[0]
    channel = next(c for c in animation.channels if c.target.node == node and c.target.path == "translation")
    accessor = gltf.accessors[animation.samplers[channel.sampler].output]
    view = gltf.bufferViews[accessor.bufferView]
    data = gltf.binary_blob()[view.byteOffset:view.byteOffset + view.byteLength]
    return np.frombuffer(data, dtype=np.float32).reshape(accessor.count, 3)


def test_render_bvh_sync_wav_puts_frame_0_at_the_wavs_time_0(tiny_gltf_render: Path) -> None:
    """With --bvh-sync wav the BVH's frame k is the glTF's key k (WAV time k / rate: the glTF test shows it lines
    up with the strikes heard): the root's position is the same in both, frame by frame. The render: SCORE with
    ``--gltf --bvh-sync wav`` (tests/conftest.py's, shared with the glTF tests)."""
    out = tiny_gltf_render
    report = json.loads((out / "report.json").read_text())
    assert report["bvh"] == {"file": "performance.bvh", "frames": len(motion_rows(out / "performance.bvh")),
                             "rate_hz": 60.0, "sync": "wav", "start_s": -0.05, "wav_time_s": 0.0,
                             "wav_offset_frames": 0.0, "units": "m", "facing": "+z"}
    rows = motion_rows(out / "performance.bvh")
    pelvis = _gltf_translation(out / "performance.glb", "pelvis")  # z up under the glTF's root
    keys = min(len(rows), len(pelvis))
    assert keys > 200
    bvh_root = rows[:keys, :3]  # the root's position channels: y up, facing +z: (x, y, z) -> (-x, z, y)
    assert np.allclose(bvh_root, pelvis[:keys] @ Y_UP[report["bvh"]["facing"]].T, atol=1e-5)
    assert np.all(rows[:4] == rows[0]) and not np.all(rows[4] == rows[0])  # held to the first pose (0.051 s)


def test_the_pose_synced_bvh_says_where_it_falls_in_the_wav(tmp_path: Path,
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    """With ``--bvh-sync pose`` frame 0 is the first pose (rig time 1 ms): report.json says it is heard 0.051 s into
    the WAV, 3.06 frames at 60 Hz, the shift that lines the BVH up in an animation tool, and so does its line. This
    was the default until 7 Dec (the test rendered without the option): an animator importing it with the WAV at
    frame 0 saw every strike 3 frames early, nothing said."""
    out = tmp_path / "out"
    assert render.main([str(SCORE), "-o", str(out), "--quiet", "--bvh-sync", "pose"]) == 0
    report = json.loads((out / "report.json").read_text())
    frames = len(motion_rows(out / "performance.bvh"))
    assert report["bvh"] == {"file": "performance.bvh", "frames": frames, "rate_hz": 60.0, "sync": "pose",
                             "start_s": 0.001, "wav_time_s": 0.051, "wav_offset_frames": 3.06, "units": "m",
                             "facing": "+z"}
    assert (f"wrote {out / 'performance.bvh'} ({frames} frames at 60 Hz; frame 0 is the first pose (--bvh-sync "
            "pose), 0.051 s into performance.wav: shift it 3.06 frames to line it up, or render with --bvh-sync "
            "wav)\n") in capsys.readouterr().out


def test_the_bvh_is_on_the_wavs_clock_by_default() -> None:
    """Until 7 Dec the default was ``pose`` (render.py and ``--help``)."""
    assert render.RenderOptions().bvh_sync == "wav"
    parser = render.build_parser()
    assert render.options_from(parser.parse_args([str(SCORE), "-o", "x"])).bvh_sync == "wav"
    assert render.options_from(parser.parse_args([str(SCORE), "-o", "x", "--bvh-sync", "pose"])).bvh_sync == "pose"
    assert "wav (the default)" in " ".join(parser.format_help().split())


def test_bvh_sync_is_said_to_do_nothing_for_the_strike_scene() -> None:
    args = render.build_parser().parse_args(["--strikes", "0.2:3", "-o", "x", "--bvh-sync", "wav"])
    assert "--bvh-sync has no effect with --strikes (the strike scene has no drummer)" in render.options_in_vain(args)


@pytest.mark.parametrize("value", ["video", ""])
def test_bvh_sync_refuses_other_values(value: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exited:
        render.build_parser().parse_args([str(SCORE), "-o", "x", "--bvh-sync", value])
    assert exited.value.code == 2 and "argument --bvh-sync: invalid choice" in capsys.readouterr().err
