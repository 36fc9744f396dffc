"""The render's progress bar counts the whole timeline the WAV holds (lead-in, music, latency, ring-out)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import soundfile as sf

from batteur import render
from batteur.progress import Progress

TINY = "tempo 120\nmeter 4/4\nSN |x.x.|\n"


def test_the_progress_total_is_the_length_of_the_rendered_wav(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    bars: list[dict[str, Any]] = []

    class Recorded(Progress):
        def __init__(self, label: str, total: float, *args: Any, **kwargs: Any) -> None:
            super().__init__(label, total, *args, **kwargs)
            self.seen = {"label": label, "total": total, "done": 0.0}
            bars.append(self.seen)

        def update(self, done: float) -> None:
            self.seen["done"] = max(self.seen["done"], done)
            super().update(done)

    monkeypatch.setattr(render, "Progress", Recorded)
    score = tmp_path / "tiny.txt"
    score.write_text(TINY)
    out = tmp_path / "out"
    assert render.main([str(score), "-o", str(out), "--quiet"]) == 0
    rendering = [b for b in bars if str(b["label"]).startswith("rendering")]
    assert len(rendering) == 1
    wav_s = sf.info(str(out / "performance.wav")).duration
    assert rendering[0]["total"] == pytest.approx(wav_s, abs=0.01)  # it was the plan and lead-in only: 1 s short
    assert rendering[0]["done"] == pytest.approx(rendering[0]["total"], abs=0.01)


def test_options_given_in_vain_are_warned_and_defaults_hold() -> None:
    parse = render.build_parser().parse_args
    assert render.options_in_vain(parse(["s.txt", "-o", "o", "--segment", "5"])) == [
        "--segment has no effect without --jobs above 1"]
    assert render.options_in_vain(parse(["s.txt", "-o", "o", "--video-fps", "25", "--video-size", "320x180"])) == [
        "--video-size has no effect without --video", "--video-fps has no effect without --video"]
    assert render.options_in_vain(parse(["s.txt", "-o", "o", "--segment", "5", "--jobs", "2", "--video",
                                         "--video-fps", "25"])) == []
    opts = render.options_from(parse(["s.txt", "-o", "o"]))
    assert (opts.segment_s, opts.video_size, opts.video_fps) == (30.0, (640, 360), 30.0)
