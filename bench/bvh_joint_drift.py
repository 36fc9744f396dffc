"""How far performance.bvh puts each joint from where physics had it.

Renders the demo (``--demo``) or a score / MIDI file with ``batteur render``, keeping every frame the BVH stream
was given (the recorded poses resampled at the file's frame times: physics' link frames, whose origins are the
joint centres), then reads the written file back with the generic reader (:mod:`common.gesture.bvh`, channels
rounded to 6 decimals as written) and prints, per joint, the largest and the median distance between the file's
forward kinematics and that frame's link origin, millimetres.

The file's frames fall between physics' poses (60 Hz poses at whole milliseconds, frames at k/60 s): a frame is
the two poses interpolated (positions linearly, orientations by slerp), which is no rigid body, so the file's
joints differ from the interpolated positions by the arc's sagitta in fast moves (tenths of a millimetre). The
last two columns take that out: physics' own poses, not resampled, converted by the same writer
(``poses.bvh``, one row per pose) and read back.

    python3 bench/bvh_joint_drift.py --demo -o /tmp/drift-demo
    python3 bench/bvh_joint_drift.py tests/data/groove_drummer1_s1_220_rock-halftime_140_fill_4-4.mid -o /tmp/d
    python3 bench/bvh_joint_drift.py --bvh /tmp/d/performance.bvh --frames /tmp/d/bvh_frames.npz  # no render
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from common.gesture.bvh import read_bvh, world_frames  # noqa: E402
from services.graphics.export.bvh import Z_UP_TO_Y_UP, BvhStream, _Layout, _rows  # noqa: E402


def record_frames(argv: list[str], demo: bool) -> tuple[list[str], np.ndarray, np.ndarray, np.ndarray]:
    """Run the render, returning the link names, every frame (F, L, 7) the BVH stream turned into a row, which of
    them fall on a pose physics sent (F,) (the others are interpolated between two poses), and physics' poses
    (P, L, 7)."""
    names: list[str] = []
    frames: list[np.ndarray] = []
    on_pose: list[bool] = []
    pose_times: list[float] = []
    poses: list[np.ndarray] = []
    restart, to_row, add = BvhStream.restart, BvhStream._frame, BvhStream.add

    def on_restart(self: BvhStream, new: list[str]) -> None:
        names[:] = list(new)
        frames.clear()
        on_pose.clear()
        pose_times.clear()
        poses.clear()
        restart(self, new)

    def on_add(self: BvhStream, time: float, values: np.ndarray) -> None:
        pose_times.append(time)
        poses.append(np.array(values, dtype=float))
        add(self, time, values)

    def on_frame(self: BvhStream, frame: np.ndarray) -> None:
        t = self._t0 + self._next / self.rate_hz  # this frame's time, seconds
        frames.append(np.array(frame, dtype=float))
        on_pose.append(any(abs(t - p) < 1e-9 for p in pose_times[-2:]))  # u = 0 or 1 between two poses
        to_row(self, frame)

    BvhStream.restart, BvhStream._frame, BvhStream.add = on_restart, on_frame, on_add  # type: ignore[method-assign,assignment]
    try:
        if demo:
            from batteur import demo as demo_cli
            code = demo_cli.main([*argv, "--quiet"])
        else:
            from batteur import render
            code = render.main([*argv, "--quiet"])
    finally:
        BvhStream.restart, BvhStream._frame, BvhStream.add = restart, to_row, add  # type: ignore[method-assign]
    if code != 0:
        raise SystemExit(code)
    return names, np.stack(frames), np.array(on_pose), np.stack(poses)


def write_rows(path: Path, names: list[str], poses: np.ndarray) -> None:
    """A BVH of ``poses`` (P, L, 7) as they are, one row each (the writer's conversion, no resampling)."""
    layout = _Layout.of(names, poses[0])
    motion, _, _ = layout.motion(poses)
    path.write_text("\n".join([*layout.header(len(poses), 1 / 60), *_rows(motion)]) + "\n", encoding="utf-8")


def drift(bvh_path: Path, names: list[str], frames: np.ndarray) -> dict[str, np.ndarray]:
    """Joint name -> distance (F,) metres between the file's forward kinematics and the frame's link origin."""
    bvh = read_bvh(bvh_path)
    if len(bvh.motion) > len(frames):
        raise SystemExit(f"{bvh_path}: {len(bvh.motion)} rows, only {len(frames)} recorded frames")
    _, positions = world_frames(bvh)
    physics = frames[:len(bvh.motion), :, :3] @ Z_UP_TO_Y_UP.T  # y up, as the file
    out: dict[str, np.ndarray] = {}
    for joint, pos in zip(bvh.joints, positions, strict=True):
        if joint.name in names:  # a joint of the file that is no link (none, or the throne) has no position
            out[joint.name] = np.linalg.norm(pos - physics[:, names.index(joint.name)], axis=1)
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("score", nargs="?", help="score or MIDI file to render (not with --demo or --bvh)")
    parser.add_argument("--demo", action="store_true", help="render the demo")
    parser.add_argument("-o", "--output", type=Path, help="render's output folder")
    parser.add_argument("--bvh", type=Path, help="compare this file (no render) ...")
    parser.add_argument("--frames", type=Path, help="... with the frames saved by an earlier run (bvh_frames.npz)")
    opts = parser.parse_args()
    if opts.bvh is not None:
        saved = np.load(opts.frames)
        names, frames, path = [str(n) for n in saved["names"]], saved["frames"], opts.bvh
        on_pose, poses = saved["on_pose"], saved["poses"]
    else:
        if opts.output is None or (opts.score is not None) == opts.demo:
            parser.error("give -o and either a score or --demo")
        names, frames, on_pose, poses = record_frames([*([] if opts.demo else [opts.score]), "-o",
                                                       str(opts.output)], opts.demo)
        np.savez_compressed(opts.output / "bvh_frames.npz", names=np.array(names), frames=frames, on_pose=on_pose,
                            poses=poses)
        path = opts.output / "performance.bvh"
    distances = drift(path, names, frames)
    every = np.stack(list(distances.values()))  # (joints, F)
    own = path.with_name("poses.bvh")
    write_rows(own, names, poses)
    at_poses = drift(own, names, poses)
    exact = np.stack([at_poses[j] for j in distances])  # (joints, P)
    print(f"{path}: {every.shape[1]} frames ({int(on_pose.sum())} on a pose), {len(distances)} joints; "
          f"{own.name}: physics' {len(poses)} poses; distances in mm")
    print(f"{'joint':<18} {'max':>9} {'median':>9} {'worst frame':>12} {'max at poses':>13} {'median at poses':>16}")
    for (joint, d), e in zip(distances.items(), exact, strict=True):
        print(f"{joint:<18} {1e3 * d.max():9.4f} {1e3 * np.median(d):9.4f} {int(np.argmax(d)):12d} "
              f"{1e3 * e.max():13.4f} {1e3 * np.median(e):16.4f}")
    print(f"{'all':<18} {1e3 * every.max():9.4f} {1e3 * np.median(every):9.4f} {'':12} {1e3 * exact.max():13.4f} "
          f"{1e3 * np.median(exact):16.4f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
