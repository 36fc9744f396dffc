"""Offline video speed: frames rendered per second at 640x360 (TinyRenderer, CPU), with and without encoding.

Prints figures; asserts nothing. Short by default (``--seconds 2``). With
``--score FILE`` it also times ``batteur render FILE --video`` (physics' 57-DOF
drummer and the kit; the video part only, from report.json).

    python bench/graphics_video.py [--seconds S] [--width W --height H] [--fps F] [--score FILE]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np
import soundfile

from common.arg_types import count, hertz, seconds
from services.graphics.figure import synthetic_performance
from services.graphics.video import render_frames, render_video


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=seconds, default=2.0, help="performance length, seconds")
    parser.add_argument("--width", type=count, default=640)
    parser.add_argument("--height", type=count, default=360)
    parser.add_argument("--fps", type=hertz, default=30.0)
    parser.add_argument("--score", type=Path, default=None, help="also time `batteur render SCORE --video`")
    args = parser.parse_args()
    sequence, impacts = synthetic_performance(duration=args.seconds, rate_hz=60.0)
    times = np.arange(int(args.seconds * args.fps)) / args.fps
    t0 = time.perf_counter()
    frames = render_frames(sequence, impacts, times, width=args.width, height=args.height)
    render_s = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as tmp:
        wav = Path(tmp) / "silence.wav"
        soundfile.write(wav, np.zeros(int(args.seconds * 48000)), 48000)
        t0 = time.perf_counter()
        info = render_video(sequence, impacts, wav, Path(tmp), fps=args.fps, width=args.width, height=args.height)
        video_s = time.perf_counter() - t0
        size = info.path.stat().st_size
    print(f"offline frames at {args.width}x{args.height}, {frames} frames ({args.seconds:g} s at {args.fps:g} fps)")
    print(f"  render only (TinyRenderer):  {frames / render_s:7.1f} frames/s  "
          f"({1000 * render_s / frames:.1f} ms/frame)")
    print(f"  render + H.264/AAC encode:   {info.frames / video_s:7.1f} frames/s  "
          f"({video_s / args.seconds:.2f} x real time, {size / 1024:.0f} KiB)")
    if args.score is not None:
        from batteur import render

        with tempfile.TemporaryDirectory() as tmp:
            code = render.main([str(args.score), "-o", tmp, "--quiet", "--video", "--video-size",
                                f"{args.width}x{args.height}", "--video-fps", f"{args.fps:g}"])
            if code != 0:
                raise SystemExit(code)
            video = json.loads((Path(tmp) / "report.json").read_text())["video"]
        print(f"batteur render {args.score.name} --video (physics' drummer): {video['frames']} frames in "
              f"{video['wall_time_s']:.2f} s = {video['frames'] / video['wall_time_s']:.1f} frames/s "
              f"(render + encode, {video['wall_time_s'] / video['duration_s']:.2f} x real time)")


if __name__ == "__main__":
    main()
