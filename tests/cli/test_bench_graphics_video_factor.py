"""``bench/graphics_video.py`` prints its real-time factors as every other bench does: seconds of video per second of
wall time, higher is faster. It printed wall time over duration ("0.87 x real time" for a render faster than real
time), the inverse. (The renderer, the encoder, the clock and ``batteur render`` are replaced by stand-ins with
known times: nothing is measured.)"""

from __future__ import annotations

import importlib.util
import json
import sys
import types
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

BENCH = Path(__file__).resolve().parents[2] / "bench" / "graphics_video.py"
SCORE = Path(__file__).resolve().parents[1] / "graphics" / "tiny_score.txt"


def _module() -> types.ModuleType:
    spec = importlib.util.spec_from_file_location("bench_graphics_video_factor", BENCH)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def test_the_factors_are_video_seconds_per_wall_second(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    from batteur import render

    module = _module()
    ticks: Iterator[float] = iter([0.0, 0.5, 10.0, 11.0])  # frames 0.5 s; render + encode 1 s
    monkeypatch.setattr(module, "time", types.SimpleNamespace(perf_counter=lambda: next(ticks)))
    monkeypatch.setattr(module, "render_frames", lambda *args, **kwargs: 60)

    def fake_video(sequence: Any, impacts: Any, wav: Path, folder: Path, **kwargs: Any) -> Any:
        path = folder / "performance.mp4"
        path.write_bytes(b"\0" * 2048)
        return types.SimpleNamespace(frames=60, path=path)

    def fake_render(argv: list[str]) -> int:  # 6 frames of 0.2 s of video, rendered and encoded in 0.5 s
        out = Path(argv[argv.index("-o") + 1])
        (out / "report.json").write_text(json.dumps({"video": {"frames": 6, "wall_time_s": 0.5, "duration_s": 0.2}}))
        return 0

    monkeypatch.setattr(module, "render_video", fake_video)
    monkeypatch.setattr(render, "main", fake_render)
    module.main(["--seconds", "2", "--width", "16", "--height", "16", "--score", str(SCORE)])
    out = capsys.readouterr().out
    assert "60.0 frames/s  (real-time factor 2.00x, 2 KiB)" in out  # 2 s of video in 1 s: twice real time
    assert "6 frames in 0.50 s = 12.0 frames/s (render + encode, real-time factor 0.40x)" in out  # 0.2 s in 0.5 s
    assert "x real time" not in out
