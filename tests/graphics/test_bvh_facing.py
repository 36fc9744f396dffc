"""Which way the drummer faces in performance.bvh (``write_bvh``'s ``facing``, ``batteur render --bvh-facing``).

The BVH faced -z while the glTF of the same render faced +z (glTF's front, fixed on 7 Dec): CMU's and Mixamo's clips
face +z, so retargeting needed a half turn and Blender's BVH import showed the drummer's back to its front camera.
The default is now +z, the glTF's; -z keeps the files before 8 Dec. Both are read alike by the BVH reader (skeleton
lengths, joint limits): it tells front from the rest pose, not from the file's axes.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from common.gesture.bvh import forward_kinematics, read_bvh
from services.graphics.export import write_bvh
from services.graphics.export.bvh import BVH_FACINGS, DEFAULT_FACING, Y_UP, BvhStream
from services.graphics.export.gltf import ROOT_ROTATION
from services.graphics.sequence import PoseSequence
from services.physics.bvh_motion import bvh_segment_lengths, load_bvh_clip
from tests.graphics.physics_poses import posed_frames


@pytest.fixture(scope="module")
def strokes() -> PoseSequence:
    """Physics' link frames over a few poses: the pelvis rocking, the arms raised and lowered, a leg bent."""
    frames = [{"seat": (5.0 * k, -4.0 * k, 3.0 * k), "right_shoulder": (40.0 + 10 * k, 10.0, 0.0),
               "right_elbow": (50.0 + 15 * k, 0.0, 10.0), "left_shoulder": (30.0, -10.0, -5.0 * k),
               "left_hip": (70.0, -8.0, 5.0), "right_knee": (-60.0 - 5 * k, 0.0, 0.0)} for k in range(5)]
    return posed_frames(frames)


def _channels(path: Path) -> list[str]:
    return [line.strip() for line in path.read_text().splitlines() if line.strip().startswith("CHANNELS")]


def test_the_default_faces_as_the_gltf(strokes: PoseSequence, tmp_path: Path) -> None:
    """Facing +z by default: every joint (and the sticks' tips) where the glTF's root puts physics' link, the
    sticks' tips in front of the pelvis (+z) and the left hip at +x, as a CMU or Mixamo clip has them."""
    assert DEFAULT_FACING == "+z" and set(BVH_FACINGS) == set(Y_UP) == {"+z", "-z"}
    assert np.allclose(Y_UP["+z"], Rotation.from_quat(ROOT_ROTATION).as_matrix(), atol=1e-12)
    path = tmp_path / "default.bvh"
    info = write_bvh(strokes, path, rate_hz=60.0)
    assert info.max_error < 1e-6
    placed = forward_kinematics(read_bvh(path))
    names = list(strokes.names)
    gltf = Rotation.from_quat(ROOT_ROTATION).as_matrix()
    for frame in range(len(strokes.times)):
        for name in (n for n in info.joints if n in names):
            want = gltf @ strokes.values[frame, names.index(name), :3]
            assert np.linalg.norm(placed[name][frame] - want) < 1e-5, (frame, name)
    assert np.all(placed["left_stick_end"][:, 2] - placed["pelvis"][:, 2] > 0.2)  # metres in front of him
    assert np.all(placed["left_thigh"][:, 0] > placed["right_thigh"][:, 0])  # his left at +x


def test_minus_z_is_the_files_before_8_dec(strokes: PoseSequence, tmp_path: Path) -> None:
    """``facing="-z"``: (x, y, z) -> (x, z, -y), the sticks at -z as the animator found them (they struck at
    z ~ -0.42 m), the same channel orders as +z (the half turn about y keeps each joint's middle angle's size) with
    the x and z angles negated (up to whole turns), the y angles and the root's height the same."""
    for facing in BVH_FACINGS:
        info = write_bvh(strokes, tmp_path / f"{facing}.bvh", rate_hz=60.0, facing=facing)
        assert info.max_error < 1e-6, facing
    minus, plus = tmp_path / "-z.bvh", tmp_path / "+z.bvh"
    placed = forward_kinematics(read_bvh(minus))
    names = list(strokes.names)
    for frame in range(len(strokes.times)):
        for link in ("pelvis", "head", "left_hand", "right_stick", "right_foot"):
            want = Y_UP["-z"] @ strokes.values[frame, names.index(link), :3]
            assert np.linalg.norm(placed[link][frame] - want) < 1e-5, (frame, link)
    assert np.all(placed["left_stick_end"][:, 2] - placed["pelvis"][:, 2] < -0.2)  # in front of him: -z
    assert _channels(minus) == _channels(plus)
    a, b = read_bvh(minus), read_bvh(plus)
    column = 0
    for joint in a.joints:
        for channel in joint.channels:
            if channel[1:] == "rotation":
                sign = 1.0 if channel[0] == "Y" else -1.0
                turns = (a.motion[:, column] - sign * b.motion[:, column]) / 360.0
                assert np.allclose(turns, np.round(turns), atol=1e-6), (joint.name, channel)
            elif channel == "Yposition":
                assert np.allclose(a.motion[:, column], b.motion[:, column], atol=1e-6)
            column += 1


def test_the_stream_writes_the_facing_given(strokes: PoseSequence, tmp_path: Path) -> None:
    write_bvh(strokes, tmp_path / "whole.bvh", rate_hz=60.0, facing="-z")
    stream = BvhStream(tmp_path / "streamed.bvh", 60.0, chunk_frames=2, facing="-z")
    stream.restart(list(strokes.names))
    for t, values in zip(strokes.times, strokes.values, strict=True):
        stream.add(float(t), values)
    stream.finish()
    assert (tmp_path / "streamed.bvh").read_bytes() == (tmp_path / "whole.bvh").read_bytes()
    with pytest.raises(ValueError, match="BVH facing 'z': \\+z or -z expected"):
        BvhStream(tmp_path / "x.bvh", 60.0, facing="z")  # type: ignore[arg-type]


def test_the_reader_reads_both_facings_alike(strokes: PoseSequence, tmp_path: Path) -> None:
    """A skeleton's lengths (``--skeleton-bvh``) and a clip's joint rotations (``--limits-from``, the joint limits)
    are the same from a file facing +z as from one facing -z: front is told from the rest pose (up: hips to head,
    right: left to right shoulder), so a file facing either way is not read mirrored or turned."""
    paths = {facing: tmp_path / f"{facing}.bvh" for facing in BVH_FACINGS}
    for facing, path in paths.items():
        write_bvh(strokes, path, rate_hz=60.0, facing=facing)
    assert bvh_segment_lengths(paths["+z"], units="m") == pytest.approx(bvh_segment_lengths(paths["-z"], units="m"))
    plus, minus = load_bvh_clip(paths["+z"]), load_bvh_clip(paths["-z"])
    assert set(plus.rotations) == set(minus.rotations) and len(plus.rotations) > 10
    for joint, rotations in plus.rotations.items():
        apart = (rotations.inv() * minus.rotations[joint]).magnitude()
        assert float(np.max(apart)) < 1e-4, joint  # radians
    elbow = plus.rotations["right_elbow"].as_euler("xyz", degrees=True)
    assert np.ptp(elbow[:, 0]) > 30.0  # the clip moves: the comparison is not of rest poses only
