"""Commands the exit-status convention (README, "Exit status") had not reached: ``batteur evaluate``'s
``--reuse``, ``python -m common.score`` and the recogniser benchmark's error lines.

No case renders: a render is stopped once the score's warnings are printed, and ``--reuse`` is asked about render
folders written by hand."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from batteur import evaluate, render
from batteur.impact_log import COLUMNS

TINY = "tempo 120\nmeter 4/4\nSN |x.x.|\n"
"""One bar, two snare notes."""


def _render_folder(folder: Path, **report: Any) -> Path:
    """A render directory as `batteur render` writes one (no impacts), its report overridden by ``report``."""
    folder.mkdir(parents=True)
    (folder / "score.txt").write_text(TINY, encoding="utf-8")
    (folder / "impacts.csv").write_text(",".join(COLUMNS) + "\n", encoding="utf-8")
    base = {"scene": "drummer", "score": "tiny.txt", "kit": "default", "grip": "german", "nuance": "tenuto",
            "tempo_scale": 1.0, "control": "cartesian", "calibration": None, "issues": [], "score_offset_s": 1.5,
            "duration_s": 4.0, "wall_time_s": 3.0, "cpu_time_s": 3.0, "real_time_factor": 1.3,
            "physics": {"contacts_sent": 10, "cpu_time_s": 3.0}}
    (folder / "report.json").write_text(json.dumps({**base, **report}), encoding="utf-8")
    return folder


def _segmented(segment_s: float, jobs: int) -> dict[str, Any]:
    """report.json's physics entry of a render on ``jobs`` processes in segments of ``segment_s`` seconds."""
    return {"contacts_sent": 10, "cpu_time_s": 3.0,
            "segments": {"count": 1, "segment_s": segment_s, "warmup_s": 3.0, "jobs": jobs}}


def test_reuse_tells_a_segmented_render_from_a_one_process_render(tmp_path: Path) -> None:
    """``--jobs`` above 1 renders another performance than one process (each segment's drummer starts afresh),
    the same for any number of processes, and another again for another ``--segment``."""
    score = tmp_path / "tiny.txt"
    score.write_text(TINY, encoding="utf-8")
    whole = _render_folder(tmp_path / "whole")
    in_30s = _render_folder(tmp_path / "in_30s", physics=_segmented(30.0, 2))
    one_process = render.RenderOptions()
    assert evaluate.reusable(whole, score, one_process)
    assert not evaluate.reusable(in_30s, score, one_process)  # was taken: its segments were not compared
    assert not evaluate.reusable(whole, score, render.RenderOptions(jobs=2))
    assert evaluate.reusable(in_30s, score, render.RenderOptions(jobs=2))
    assert evaluate.reusable(in_30s, score, render.RenderOptions(jobs=4, segment_s=30.0))  # any N above 1
    assert not evaluate.reusable(in_30s, score, render.RenderOptions(jobs=2, segment_s=10.0))
    old = _render_folder(tmp_path / "old")  # a report written before physics' entry: a one-process render's
    (old / "report.json").write_text(json.dumps({k: v for k, v in json.loads((old / "report.json").read_text())
                                                 .items() if k != "physics"}), encoding="utf-8")
    assert evaluate.reusable(old, score, one_process)
    assert not evaluate.reusable(old, score, render.RenderOptions(jobs=2))


@pytest.mark.parametrize("argv, named", [(["{missing}"], "missing.txt"), (["{score}", "--kit", "nosuch"], "nosuch")])
def test_common_score_refuses_a_file_it_cannot_use_with_1_and_its_name(argv: list[str], named: str,
                                                                      tmp_path: Path,
                                                                      capsys: pytest.CaptureFixture[str]) -> None:
    from common.score.__main__ import main

    score = tmp_path / "tiny.txt"
    score.write_text(TINY, encoding="utf-8")
    files = {"missing": str(tmp_path / "missing.txt"), "score": str(score)}
    assert main([a.format(**files) for a in argv]) == 1  # was 2, as a command line it cannot run
    err = capsys.readouterr().err
    assert err.startswith("python -m common.score: error: ") and named in err  # was "error: ..."
    assert len(err.splitlines()) == 1


def test_the_recogniser_bench_names_itself_when_its_kit_is_not_installed(monkeypatch: pytest.MonkeyPatch,
                                                                          capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("mir_eval")  # the benchmark scores with it
    from services.recogniser.training.kits import KitsMissingError
    from tests.test_bench_cli import bench

    module = bench("recogniser_bench")

    def missing(names: object) -> None:
        raise KitsMissingError("hydrogen drum kits not found: The Black Pearl 1.0 (apt-get install hydrogen-drumkits)")

    monkeypatch.setattr(module, "require_kits", missing)
    monkeypatch.setattr(module, "parse_args", lambda argv, ap: ap.parse_args(argv))  # the kit name is not checked
    prog = module.build_parser().prog
    assert module.main([]) == 1
    assert capsys.readouterr().err == f"{prog}: error: hydrogen drum kits not found: The Black Pearl 1.0 " \
                                      "(apt-get install hydrogen-drumkits)\n"  # was "error: ..."
