"""Offline video speed: frames rendered per second at 640x360 (TinyRenderer, CPU), with and without encoding.

Prints figures; asserts nothing. Short by default (``--seconds 2``).

    python bench/graphics_video.py [--seconds S] [--width W --height H] [--fps F]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import soundfile

from services.graphics.figure import synthetic_performance
from services.graphics.video import render_frames, render_video


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=2.0, help="performance length, seconds")
    parser.add_argument("--width", type=int, default=640)
    parser.add_argument("--height", type=int, default=360)
    parser.add_argument("--fps", type=float, default=30.0)
    args = parser.parse_args()
    sequence, impacts = synthetic_performance(duration=args.seconds, rate_hz=60.0)
    times = np.arange(int(args.seconds * args.fps)) / args.fps
    t0 = time.perf_counter()
    count = render_frames(sequence, impacts, times, width=args.width, height=args.height)
    render_s = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as tmp:
        wav = Path(tmp) / "silence.wav"
        soundfile.write(wav, np.zeros(int(args.seconds * 48000)), 48000)
        t0 = time.perf_counter()
        info = render_video(sequence, impacts, wav, Path(tmp), fps=args.fps, width=args.width, height=args.height)
        video_s = time.perf_counter() - t0
        size = info.path.stat().st_size
    print(f"offline frames at {args.width}x{args.height}, {count} frames ({args.seconds:g} s at {args.fps:g} fps)")
    print(f"  render only (TinyRenderer):  {count / render_s:7.1f} frames/s  ({1000 * render_s / count:.1f} ms/frame)")
    print(f"  render + H.264/AAC encode:   {info.frames / video_s:7.1f} frames/s  "
          f"({video_s / args.seconds:.2f} x real time, {size / 1024:.0f} KiB)")


if __name__ == "__main__":
    main()
