"""Offline video speed: frames rendered per second at 640x360 (TinyRenderer, CPU), with and without encoding.

Prints figures; asserts nothing. Short by default (``--seconds 2``). The real-time factor is seconds of video
per second of wall time, as every bench's: above 1 is faster than real time (until 7 Dec it printed the inverse,
"x real time" lower is faster). With
``--score FILE`` it also times ``batteur render FILE --video`` (physics' 57-DOF
drummer and the kit; the video part only, from report.json).

    python bench/graphics_video.py [--seconds S] [--width W --height H] [--fps F] [--score FILE]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import soundfile

from common.arg_types import count, hertz, seconds
from services.graphics.figure import synthetic_performance
from services.graphics.video import render_frames, render_video

VIDEO_SIZE = (16, 7680, 16, 4320)
"""Frame sizes ``batteur render --video`` accepts: even widths 16 to 7680, even heights 16 to 4320, pixels."""
VIDEO_FPS = (1.0, 240.0)
"""Frame rates it accepts, frames per second."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=seconds, default=2.0, help="performance length, seconds (default 2)")
    parser.add_argument("--width", type=count, default=640, help="frame width, pixels, even, 16 to 7680 (default 640)")
    parser.add_argument("--height", type=count, default=360,
                        help="frame height, pixels, even, 16 to 4320 (default 360)")
    parser.add_argument("--fps", type=hertz, default=30.0, help="frames per second, 1 to 240 (default 30)")
    parser.add_argument("--score", type=Path, default=None, help="also time `batteur render SCORE --video`")
    return parser


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    """The options, checked before the frames are rendered (H.264 refuses odd sizes only after them)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    w_min, w_max, h_min, h_max = VIDEO_SIZE
    if args.width % 2 or args.height % 2 or not (w_min <= args.width <= w_max and h_min <= args.height <= h_max):
        parser.error(f"--width {args.width} --height {args.height}: even numbers, {w_min}x{h_min} to {w_max}x{h_max}")
    if not VIDEO_FPS[0] <= args.fps <= VIDEO_FPS[1]:
        parser.error(f"--fps {args.fps:g}: {VIDEO_FPS[0]:g} to {VIDEO_FPS[1]:g} frames per second")
    if int(args.seconds * args.fps) < 1:
        parser.error(f"--seconds {args.seconds:g} at --fps {args.fps:g}: not one frame")
    if args.score is not None:
        from common.score.text import read_score

        if not args.score.is_file():
            parser.error(f"--score {args.score}: no such file")
        try:  # a score render refuses, refused before the frames are timed rather than after
            read_score(args.score)
        except (ValueError, OSError) as exc:  # ScoreError is a ValueError
            parser.error(f"--score {exc}")
    return args


def main(argv: Sequence[str] | None = None) -> None:
    args = parse_args(argv)
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
          f"(real-time factor {args.seconds / video_s:.2f}x, {size / 1024:.0f} KiB)")
    if args.score is not None:
        from batteur import render

        with tempfile.TemporaryDirectory() as tmp, contextlib.redirect_stdout(io.StringIO()):
            # its "wrote <tmp>/..." lines would name files deleted below; its errors and progress go to stderr
            code = render.main([str(args.score), "-o", tmp, "--video", "--video-size",
                                f"{args.width}x{args.height}", "--video-fps", f"{args.fps:g}"])
            if code != 0:
                raise SystemExit(code)
            video = json.loads((Path(tmp) / "report.json").read_text())["video"]
        print(f"batteur render {args.score.name} --video (physics' drummer): {video['frames']} frames in "
              f"{video['wall_time_s']:.2f} s = {video['frames'] / video['wall_time_s']:.1f} frames/s "
              f"(render + encode, real-time factor {video['duration_s'] / video['wall_time_s']:.2f}x)")


if __name__ == "__main__":
    main()
