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

Physics' positions are turned into the file's axes as the file faces (``--bvh-facing``, +z by default since 8 Dec):
the stream's own facing for a render, else the one saved with the frames, else report.json's ``bvh.facing`` beside
the file (none: -z, a file from before 8 Dec).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from batteur.render import facing_joined  # noqa: E402
from common.gesture.bvh import read_bvh, world_frames  # noqa: E402
from services.graphics.export.bvh import BVH_FACINGS, Y_UP, BvhFacing, BvhStream, _Layout, _rows  # noqa: E402


def record_frames(argv: list[str], demo: bool) -> tuple[list[str], np.ndarray, np.ndarray, np.ndarray, BvhFacing]:
    """Run the render, returning the link names, every frame (F, L, 7) the BVH stream turned into a row, which of
    them fall on a pose physics sent (F,) (the others are interpolated between two poses), physics' poses
    (P, L, 7) and which way the file faces."""
    facing: list[BvhFacing] = []
    names: list[str] = []
    frames: list[np.ndarray] = []
    on_pose: list[bool] = []
    pose_times: list[float] = []
    poses: list[np.ndarray] = []
    restart, to_row, add = BvhStream.restart, BvhStream._frame, BvhStream.add

    def on_restart(self: BvhStream, new: list[str]) -> None:
        names[:] = list(new)
        facing[:] = [self.facing]
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
    return names, np.stack(frames), np.array(on_pose), np.stack(poses), facing[0]


def write_rows(path: Path, names: list[str], poses: np.ndarray, facing: BvhFacing) -> None:
    """A BVH of ``poses`` (P, L, 7) as they are, one row each (the writer's conversion, no resampling), facing
    ``facing``."""
    layout = _Layout.of(names, poses[0], facing=facing)
    motion, _, _ = layout.motion(poses)
    path.write_text("\n".join([*layout.header(len(poses), 1 / 60), *_rows(motion)]) + "\n", encoding="utf-8")


def drift(bvh_path: Path, names: list[str], frames: np.ndarray, facing: BvhFacing) -> dict[str, np.ndarray]:
    """Joint name -> distance (F,) metres between the file's forward kinematics and the frame's link origin, the
    file facing ``facing``."""
    bvh = read_bvh(bvh_path)
    if len(bvh.motion) > len(frames):
        raise SystemExit(f"{bvh_path}: {len(bvh.motion)} rows, only {len(frames)} recorded frames")
    _, positions = world_frames(bvh)
    physics = frames[:len(bvh.motion), :, :3] @ Y_UP[facing].T  # y up, as the file
    out: dict[str, np.ndarray] = {}
    for joint, pos in zip(bvh.joints, positions, strict=True):
        if joint.name in names:  # a joint of the file that is no link (none, or the throne) has no position
            out[joint.name] = np.linalg.norm(pos - physics[:, names.index(joint.name)], axis=1)
    return out


def file_facing(bvh_path: Path) -> BvhFacing:
    """Which way ``bvh_path`` faces, as report.json beside it says (``bvh.facing``); -z without one (the files
    before 8 Dec, whose reports have no facing)."""
    report = bvh_path.with_name("report.json")
    entry = json.loads(report.read_text()).get("bvh") if report.is_file() else None
    facing = (entry or {}).get("facing", "-z")
    if facing not in BVH_FACINGS:
        raise SystemExit(f"{report}: bvh.facing {facing!r}: {' or '.join(BVH_FACINGS)} expected")
    return facing  # type: ignore[no-any-return]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("score", nargs="?", help="score or MIDI file to render (not with --demo or --bvh)")
    parser.add_argument("--demo", action="store_true", help="render the demo")
    parser.add_argument("-o", "--output", type=Path, help="render's output folder")
    parser.add_argument("--bvh", type=Path, help="compare this file (no render) ...")
    parser.add_argument("--frames", type=Path, help="... with the frames saved by an earlier run (bvh_frames.npz)")
    parser.add_argument("--bvh-facing", choices=BVH_FACINGS, default=None,
                        help="the render's --bvh-facing (not with --demo: the demo's is the default, +z)")
    opts = parser.parse_args(facing_joined(sys.argv[1:]))  # "--bvh-facing -z": "-z" is no option
    if opts.bvh is not None:
        saved = np.load(opts.frames)
        names, frames, path = [str(n) for n in saved["names"]], saved["frames"], opts.bvh
        on_pose, poses = saved["on_pose"], saved["poses"]
        facing = str(saved["facing"]) if "facing" in saved else file_facing(path)
    else:
        if opts.output is None or (opts.score is not None) == opts.demo:
            parser.error("give -o and either a score or --demo")
        passed = [] if opts.bvh_facing is None else [f"--bvh-facing={opts.bvh_facing}"]
        names, frames, on_pose, poses, facing = record_frames([*([] if opts.demo else [opts.score, *passed]), "-o",
                                                               str(opts.output)], opts.demo)
        np.savez_compressed(opts.output / "bvh_frames.npz", names=np.array(names), frames=frames, on_pose=on_pose,
                            poses=poses, facing=np.array(facing))
        path = opts.output / "performance.bvh"
    distances = drift(path, names, frames, facing)
    every = np.stack(list(distances.values()))  # (joints, F)
    own = path.with_name("poses.bvh")
    write_rows(own, names, poses, facing)
    at_poses = drift(own, names, poses, facing)
    exact = np.stack([at_poses[j] for j in distances])  # (joints, P)
    print(f"{path}: facing {facing}, {every.shape[1]} frames ({int(on_pose.sum())} on a pose), {len(distances)} "
          f"joints; "
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
