"""``batteur evaluate --fit-calibration`` fits for the kit its scores play. It took ``--kit`` (else the default kit)
whatever the scores' ``kit`` lines said; now, without ``--kit``, the one kit line they share (a render directory:
the kit in its report.json), and scores of different kits are refused before any render: a calibration's offsets
and velocity maps are per kit object, one fit cannot serve two kits. (The renders and the fit are replaced by
stand-ins: nothing is simulated.)"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from batteur import calibration, evaluate
from batteur.impact_log import COLUMNS

GROOVE = "tempo 120\nmeter 4/4\nSN |x.x.|\n"


def _score(path: Path, kit: str | None) -> Path:
    path.write_text((f"kit {kit}\n" if kit else "") + GROOVE)
    return path


def _render_dir(folder: Path, kit: str) -> Path:
    """A render directory as `batteur render` writes one, with no impacts."""
    folder.mkdir(parents=True)
    (folder / "score.txt").write_text(GROOVE)
    (folder / "impacts.csv").write_text(",".join(COLUMNS) + "\n")
    report = {"scene": "drummer", "score": "score.txt", "kit": kit, "issues": [], "score_offset_s": 1.5,
              "duration_s": 4.0, "wall_time_s": 3.0, "cpu_time_s": 3.0, "real_time_factor": 1.3}
    (folder / "report.json").write_text(json.dumps(report))
    return folder


@pytest.fixture
def fitted_kits(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """The kit of each fit; each score "rendered" as an empty render directory."""
    kits: list[str] = []

    def no_render(paths: list[Path], opts: Any, renders: Path | None, **kwargs: Any) -> list[evaluate.FileResult]:
        return [evaluate.evaluate_render_dir(path, _render_dir(tmp_path / f"render{k}", "default"))
                for k, path in enumerate(paths)]

    def fit(results: Any, kit: Any, base: Any = None) -> calibration.Calibration:
        kits.append(kit.name)
        return calibration.Calibration()

    monkeypatch.setattr(evaluate, "evaluate_scores", no_render)
    monkeypatch.setattr(calibration, "fit_calibration", fit)
    return kits


def _error(capsys: pytest.CaptureFixture[str]) -> str:
    lines = [line for line in capsys.readouterr().err.splitlines() if "error" in line]
    assert len(lines) == 1, lines
    return lines[0]


def test_the_kit_line_the_scores_share_is_the_fit_kit(tmp_path: Path, fitted_kits: list[str]) -> None:
    scores = [_score(tmp_path / f"{name}.txt", "double_pedal") for name in ("a", "b")]
    assert evaluate.main([*map(str, scores), "--fit-calibration", str(tmp_path / "fit.json"), "--quiet"]) == 0
    assert fitted_kits == ["double_pedal"]


def test_scores_of_different_kits_are_refused_before_the_renders(tmp_path: Path, fitted_kits: list[str],
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    a, b = _score(tmp_path / "a.txt", "double_pedal"), _score(tmp_path / "b.txt", None)
    fit = tmp_path / "fit.json"
    assert evaluate.main([str(a), str(b), "--fit-calibration", str(fit), "--quiet"]) == 2
    assert _error(capsys) == (
        "batteur evaluate: error: --fit-calibration: these inputs play 2 kits, double_pedal (a.txt); default (b.txt); "
        "a calibration is for one kit (its offsets and velocity maps are per kit object): fit each kit's apart, or "
        "give --kit to render every score on one")
    assert fitted_kits == [] and not fit.exists()


def test_a_render_directory_counts_with_the_kit_of_its_report(tmp_path: Path, fitted_kits: list[str],
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    score = _score(tmp_path / "a.txt", "double_pedal")
    take = _render_dir(tmp_path / "take1", "default")
    assert evaluate.main([str(score), str(take), "--fit-calibration", str(tmp_path / "fit.json"), "--quiet"]) == 2
    assert "double_pedal (a.txt); default (take1)" in _error(capsys)


def test_kit_given_is_the_fit_kit_whatever_the_lines(tmp_path: Path, fitted_kits: list[str]) -> None:
    a, b = _score(tmp_path / "a.txt", "double_pedal"), _score(tmp_path / "b.txt", None)
    assert evaluate.main([str(a), str(b), "--kit", "left_handed", "--fit-calibration", str(tmp_path / "fit.json"),
                          "--quiet"]) == 0
    assert fitted_kits == ["left_handed"]


def test_a_kit_line_naming_no_kit_is_said_with_its_line(tmp_path: Path, fitted_kits: list[str],
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    a = _score(tmp_path / "a.txt", "nokit")
    assert evaluate.main([str(a), "--fit-calibration", str(tmp_path / "fit.json"), "--quiet"]) == 1
    assert "a.txt: line 1: kit 'nokit'" in _error(capsys)


def test_a_kit_named_and_the_same_kit_by_its_file_are_one_kit(tmp_path: Path, fitted_kits: list[str]) -> None:
    from common.kit import KITS_DIR

    scores = [_score(tmp_path / "a.txt", "double_pedal"),
              _score(tmp_path / "b.txt", str(KITS_DIR / "double_pedal.yaml"))]
    assert evaluate.main([*map(str, scores), "--fit-calibration", str(tmp_path / "fit.json"), "--quiet"]) == 0
    assert len(fitted_kits) == 1
