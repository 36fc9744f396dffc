"""BVH export: the body's joint hierarchy and one motion frame per pose.

The tree comes from the link names (:func:`services.graphics.skeleton.guess_parents`);
links that are no body part (kit links) are left out. BVH is y-up, so the
Batteur frame (z up, drummer facing +y) is turned: ``(x, y, z) -> (x, z, -y)``;
the drummer then faces -z in the file. Units are metres by default
(``scale=100`` writes centimetres). Joint offsets are the first frame's
parent-to-child offsets; the root has position and rotation channels, the
other joints rotations only (``Zrotation Xrotation Yrotation``, degrees), or
positions too with ``all_positions=True`` (exact even for non-rigid input).
Rotation channels ZXY mean ``R = Rz Rx Ry``, as Blender and three.js read them.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from services.graphics.sequence import PoseSequence
from services.graphics.skeleton import body_links, guess_parents

Z_UP_TO_Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
"""Maps Batteur world vectors (z up) to BVH/glTF world vectors (y up): (x, y, z) -> (x, z, -y)."""


@dataclass(frozen=True)
class BvhInfo:
    """What :func:`write_bvh` wrote.

    Attributes
    ----------
    joints : list of str
        Joint names in file order (the root first).
    frames : int
        Motion frames.
    frame_time : float
        Seconds per frame.
    skipped : list of str
        Links left out (not part of the body tree).
    max_error : float
        Largest distance between a joint placed by the file's forward kinematics and its input position,
        in the file's units (0 up to float rounding for a rigid body).
    """

    joints: list[str]
    frames: int
    frame_time: float
    skipped: list[str]
    max_error: float


def _tree(names: list[str]) -> tuple[int, list[int], dict[int, list[int]]]:
    parents = guess_parents(names)
    body = set(body_links(names))
    roots = [i for i in body if parents[i] < 0]
    if not roots:
        raise ValueError("no body root link (pelvis/root/hips) among the link names")
    root = min(roots, key=lambda i: (0 if "pelvis" in names[i] or "root" in names[i] else 1, i))
    children: dict[int, list[int]] = {i: [] for i in range(len(names))}
    for i, p in enumerate(parents):
        if p >= 0 and i in body:
            children[p].append(i)
    order: list[int] = []
    stack = [root]
    while stack:
        i = stack.pop()
        order.append(i)
        stack.extend(reversed(children[i]))
    return root, order, {i: children[i] for i in order}


def write_bvh(sequence: PoseSequence, path: Path, rate_hz: float | None = None, scale: float = 1.0,
              all_positions: bool = False) -> BvhInfo:
    """Write ``sequence`` as a BVH file at ``path``.

    Parameters
    ----------
    sequence : PoseSequence
        World link poses (metres, z up).
    path : Path
        Output file.
    rate_hz : float, optional
        Frame rate; default: the sequence's own (its median pose interval). The sequence is resampled.
    scale : float
        File units per metre (1: metres, 100: centimetres).
    all_positions : bool
        Give every joint position channels too.
    """
    if rate_hz is None:
        dt = float(np.median(np.diff(sequence.times))) if len(sequence.times) > 1 else 1 / 60
        rate_hz = 1.0 / dt
    seq = sequence.resample(rate_hz)
    root, order, children = _tree(seq.names)
    parents = guess_parents(seq.names)
    c = Z_UP_TO_Y_UP
    pos = seq.values[:, :, :3] @ c.T * scale  # (N, L, 3)
    rots = [Rotation.from_matrix(c @ Rotation.from_quat(seq.values[:, i, 3:]).as_matrix() @ c.T)
            for i in range(len(seq.names))]
    first = {i: Rotation.from_quat(rots[i].as_quat()[0]) for i in order}
    offsets = {}
    for i in order:
        offsets[i] = np.zeros(3) if i == root else first[parents[i]].inv().apply(pos[0, i] - pos[0, parents[i]])

    lines = ["HIERARCHY"]
    motion_cols: list[np.ndarray] = []

    def channels(i: int) -> None:
        if i == root or all_positions:
            motion_cols.append(pos[:, i] if i == root else rots[parents[i]].inv().apply(pos[:, i] - pos[:, parents[i]]))
        local = rots[i] if i == root else rots[parents[i]].inv() * rots[i]
        with warnings.catch_warnings():  # at gimbal lock scipy picks one of the equivalent angle sets: still exact
            warnings.simplefilter("ignore", UserWarning)
            motion_cols.append(local.as_euler("ZXY", degrees=True))

    def emit(i: int, depth: int) -> None:
        pad = "  " * depth
        kind = "ROOT" if i == root else "JOINT"
        lines.append(f"{pad}{kind} {seq.names[i]}")
        lines.append(f"{pad}{{")
        ox, oy, oz = offsets[i]
        lines.append(f"{pad}  OFFSET {ox:.6f} {oy:.6f} {oz:.6f}")
        rot = "Zrotation Xrotation Yrotation"
        if i == root or all_positions:
            lines.append(f"{pad}  CHANNELS 6 Xposition Yposition Zposition {rot}")
        else:
            lines.append(f"{pad}  CHANNELS 3 {rot}")
        channels(i)
        if children[i]:
            for child in children[i]:
                emit(child, depth + 1)
        else:
            tip = offsets[i] * 0.25 if np.linalg.norm(offsets[i]) > 1e-6 else np.array([0.0, 0.05 * scale, 0.0])
            tip = first[i].inv().apply(first[parents[i]].apply(tip)) if i != root else tip
            lines.append(f"{pad}  End Site")
            lines.append(f"{pad}  {{")
            lines.append(f"{pad}    OFFSET {tip[0]:.6f} {tip[1]:.6f} {tip[2]:.6f}")
            lines.append(f"{pad}  }}")
        lines.append(f"{pad}}}")

    emit(root, 0)
    motion = np.concatenate(motion_cols, axis=1)
    frame_time = 1.0 / rate_hz
    lines += ["MOTION", f"Frames: {len(seq.times)}", f"Frame Time: {frame_time:.8f}"]
    lines += [" ".join(f"{v:.6f}" for v in row) for row in motion]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")

    # forward kinematics of what was written, against the input (reports non-rigid input)
    error = 0.0
    world_r: dict[int, Rotation] = {}
    world_p: dict[int, np.ndarray] = {}
    for i in order:
        if i == root:
            world_r[i], world_p[i] = rots[i], pos[:, i]
        else:
            p = parents[i]
            world_r[i] = world_r[p] * (rots[p].inv() * rots[i])
            offset = np.tile(offsets[i], (len(seq.times), 1))
            world_p[i] = pos[:, i] if all_positions else world_p[p] + world_r[p].apply(offset)
        error = max(error, float(np.abs(world_p[i] - pos[:, i]).max()))
    skipped = [n for k, n in enumerate(seq.names) if k not in set(order)]
    return BvhInfo([seq.names[i] for i in order], len(seq.times), frame_time, skipped, error)
