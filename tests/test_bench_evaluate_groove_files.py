"""bench/evaluate_groove.py finding no file: it says why (info.csv lists none, or the filter that removed those it
lists), not "no validation files found" of a folder holding 124. Nothing is rendered."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "bench" / "evaluate_groove.py"


@pytest.fixture(scope="module")
def groove() -> ModuleType:
    """bench/evaluate_groove.py as a module (its ``main`` is run by the tests, with a made-up dataset)."""
    spec = importlib.util.spec_from_file_location("bench_evaluate_groove_files", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses in the script look their module up
    spec.loader.exec_module(module)
    return module


def _dataset(root: Path, rows: list[tuple[str, str, float, str]]) -> Path:
    root.mkdir()
    lines = ["midi_filename,split,duration,beat_type"] + [f"{n},{s},{d},{b}" for n, s, d, b in rows]
    (root / "info.csv").write_text("\n".join(lines) + "\n")
    return root


def test_files_all_longer_than_max_duration_are_counted_and_the_limit_named(
        groove: ModuleType, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    root = _dataset(tmp_path / "groove", [("a_beat.mid", "validation", 5.0, "beat"),
                                          ("b_fill.mid", "validation", 2.5, "fill"),
                                          ("c_beat.mid", "train", 0.05, "beat")])
    assert groove.main(["--root", str(root), "--max-duration", "0.1"]) == 1
    assert capsys.readouterr().err == (
        f"evaluate_groove: error: none of the 2 validation files in {root} is within --max-duration 0.1 s "
        "(the shortest is 2.5 s; --all takes every one)\n")


def test_an_info_csv_without_validation_rows_says_so(groove: ModuleType, tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    root = _dataset(tmp_path / "groove", [("c_beat.mid", "train", 3.0, "beat")])
    assert groove.main(["--root", str(root), "--all"]) == 1
    assert capsys.readouterr().err == (f"evaluate_groove: error: no validation files in {root} (info.csv has no "
                                       "row whose split is validation)\n")
