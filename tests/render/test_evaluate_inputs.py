"""What ``batteur evaluate`` makes of the inputs a new user gives it: two scores (or two render folders) of one name
get rows and plots of their own; one input named twice counts once; a render's impacts.csv is refused with the
folder to give instead; ``--json --list`` holds the impact listing.

The renders are stand-ins (a render folder as `batteur render` writes one, two snare impacts): what is tested is
the naming, the listing and the checks, not the physics."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from batteur import evaluate
from batteur.impact_log import COLUMNS

TINY = "tempo 120\nmeter 4/4\nSN |x.x.|\n"
"""One bar, two snare notes (at 0 and 1 s)."""
OFFSET_S = 1.5
"""The stand-in renders' score_offset_s: rig time of the score's time 0, seconds."""


def _write_render(folder: Path, score: Path) -> Path:
    """A render of ``score`` into ``folder``: its copy, report.json, and an impact on each note 1 ms late."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"score{score.suffix}").write_bytes(score.read_bytes())
    rows = [",".join(COLUMNS)]
    for seq, time_s in enumerate((0.001, 1.001)):
        values = {"seq": seq, "time": OFFSET_S + time_s, "instrument": "snare", "zone": "centre", "r": 0.2,
                  "theta": 0.0, "velocity": 2.5 + seq, "impulse": 0.1, "peak_force": 20.0, "duration": 0.008,
                  "part": "left_stick_tip", "openness": -1.0}
        rows.append(",".join(str(values[c]) for c in COLUMNS))
    (folder / "impacts.csv").write_text("\n".join(rows) + "\n")
    report = {"scene": "drummer", "score": str(score), "kit": "default", "grip": "german", "nuance": "tenuto",
              "tempo_scale": 1.0, "control": "cartesian", "calibration": None, "issues": [],
              "score_offset_s": OFFSET_S, "duration_s": 4.0, "music_duration_s": 2.0, "wall_time_s": 2.0,
              "cpu_time_s": 2.5, "real_time_factor": 2.0}
    (folder / "report.json").write_text(json.dumps(report))
    return folder


@pytest.fixture
def renders(monkeypatch: pytest.MonkeyPatch) -> list[Path]:
    """Stand in for `batteur render` (the folders it was asked to render into, in order)."""
    asked: list[Path] = []

    def render_score(path: Path, out: Path, *args: Any, **kwargs: Any) -> None:
        asked.append(out)
        _write_render(out, path)

    monkeypatch.setattr("batteur.render.render_score", render_score)
    return asked


def _score(path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(TINY)
    return path


def _rows(out: str) -> list[str]:
    """The table's row labels (the label column, up to the notes count)."""
    return [line.split("  ")[0] for line in out.splitlines()[1:] if line and not line.startswith(" ")]


def _wrote(err: str) -> list[str]:
    return [line.removeprefix("wrote ") for line in err.splitlines() if line.startswith("wrote ")]


def test_two_scores_of_one_name_get_rows_and_plots_of_their_own(tmp_path: Path, renders: list[Path],
                                                                 monkeypatch: pytest.MonkeyPatch,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    """Both rows were ``groove.txt``, and the second's plots replaced the first's (``wrote P/groove_pianoroll.png``
    twice)."""
    monkeypatch.chdir(tmp_path)
    _score(Path("a/groove.txt"))
    _score(Path("b/groove.txt"))
    assert evaluate.main(["a/groove.txt", "b/groove.txt", "--plots", "P", "--quiet"]) == 0
    out, err = capsys.readouterr()
    assert len(set(renders)) == 2  # each into a temporary folder of its own (was one ``groove`` for both)
    assert _rows(out) == ["a/groove.txt", "b/groove.txt", "ALL"]
    wrote = _wrote(err)
    assert len(set(wrote)) == len(wrote) == 4, err
    assert sorted(p.name for p in Path("P").iterdir()) == ["a_groove_pianoroll.png", "a_groove_timing.png",
                                                          "b_groove_pianoroll.png", "b_groove_timing.png"]
    assert evaluate.main(["a/groove.txt", "b/groove.txt", "--json", "--quiet"]) == 0
    assert [f["name"] for f in json.loads(capsys.readouterr().out)["files"]] == ["a/groove.txt", "b/groove.txt"]


def test_two_render_folders_of_one_name_get_rows_and_plots_of_their_own(tmp_path: Path,
                                                                         monkeypatch: pytest.MonkeyPatch,
                                                                         capsys: pytest.CaptureFixture[str]) -> None:
    """Two folders ``r1`` (of two scores named alike) were two rows ``r1 (groove.txt)`` and one pair of plots."""
    monkeypatch.chdir(tmp_path)
    for where in ("x", "y"):
        _write_render(Path(where) / "r1", _score(Path(f"scores/{where}/groove.txt")))
    assert evaluate.main(["x/r1", "y/r1", "--plots", "P"]) == 0
    out, err = capsys.readouterr()
    assert _rows(out) == ["x/r1 (groove.txt)", "y/r1 (groove.txt)", "ALL"]
    assert sorted(p.name for p in Path("P").iterdir()) == ["x_r1_pianoroll.png", "x_r1_timing.png",
                                                          "y_r1_pianoroll.png", "y_r1_timing.png"]
    assert len(set(_wrote(err))) == 4


def test_a_plot_stem_that_no_path_tells_apart_is_numbered_not_overwritten(tmp_path: Path, renders: list[Path],
                                                                          monkeypatch: pytest.MonkeyPatch,
                                                                          capsys: pytest.CaptureFixture[str]) -> None:
    """A render folder ``groove`` and a score ``groove.txt`` next to it: both plots' stem was ``groove``."""
    monkeypatch.chdir(tmp_path)
    _write_render(Path("groove"), _score(Path("groove.txt")))
    assert evaluate.main(["groove", "groove.txt", "--plots", "P", "--quiet"]) == 0
    out, err = capsys.readouterr()
    assert _rows(out) == ["groove (groove.txt)", "groove.txt", "ALL"]
    assert _wrote(err) == ["P/groove_pianoroll.png", "P/groove_timing.png", "P/groove-2_pianoroll.png",
                           "P/groove-2_timing.png"]


def test_a_numbered_stem_never_takes_another_inputs_stem() -> None:
    assert evaluate._numbered(["groove", "groove", "groove-2"], "-") == ["groove", "groove-3", "groove-2"]


def test_the_same_render_folder_given_twice_counts_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    """``batteur evaluate r1 r1`` gave two rows and an ALL of twice its notes."""
    monkeypatch.chdir(tmp_path)
    _write_render(Path("r1"), _score(Path("groove.txt")))
    assert evaluate.main(["r1", "./r1/", str(tmp_path / "r1"), "--json"]) == 0
    out, err = capsys.readouterr()
    figures = json.loads(out)
    assert [f["name"] for f in figures["files"]] == ["r1 (groove.txt)"]
    assert figures["aggregate"]["notes"] == 2
    assert err.splitlines() == ["batteur evaluate: warning: r1 is given twice: evaluated once",
                                f"batteur evaluate: warning: r1 is given again as {tmp_path / 'r1'}: evaluated once"]


def test_the_same_score_given_twice_is_rendered_once(tmp_path: Path, renders: list[Path],
                                                     monkeypatch: pytest.MonkeyPatch,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    _score(Path("groove.txt"))
    assert evaluate.main(["groove.txt", "groove.txt", "--quiet"]) == 0
    out, err = capsys.readouterr()
    assert _rows(out) == ["groove.txt"] and len(renders) == 1
    assert "groove.txt is given twice: evaluated once" in err


@pytest.mark.parametrize("name", ["impacts.csv", "report.json"])
def test_a_renders_file_is_refused_with_the_folder_to_give(name: str, tmp_path: Path, renders: list[Path],
                                                           monkeypatch: pytest.MonkeyPatch,
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    """impacts.csv was read as a text score: ``line 1: unknown directive 'seq,time,instrument,...'``. It is checked
    before any render (the score given first is not rendered)."""
    monkeypatch.chdir(tmp_path)
    _write_render(Path("r1"), _score(Path("groove.txt")))
    assert evaluate.main(["groove.txt", f"r1/{name}"]) == 1
    err = capsys.readouterr().err
    assert err == (f"batteur evaluate: error: r1/{name}: a render's {name}, not a score; give its render folder: "
                   "batteur evaluate r1\n")
    assert renders == []


def test_an_impact_log_by_another_name_is_known_by_its_header(tmp_path: Path, renders: list[Path],
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "take1.csv"
    log.write_bytes((_write_render(tmp_path / "r1", _score(tmp_path / "groove.txt")) / "impacts.csv").read_bytes())
    assert evaluate.main([str(log)]) == 1
    assert capsys.readouterr().err == (f"batteur evaluate: error: {log}: a render's impact log, not a score; give "
                                       "the render folder it came from\n")
    assert renders == []


def test_json_with_list_holds_every_impact(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``--json --list`` printed the JSON without the listing, in silence."""
    folder = _write_render(tmp_path / "r1", _score(tmp_path / "groove.txt"))
    assert evaluate.main([str(folder), "--json", "--list"]) == 0
    (figures,) = json.loads(capsys.readouterr().out)["files"]
    first, second = figures["impact_list"]
    assert first == {"matched": True, "time_s": 0.001, "instrument": "snare", "part": "left_stick_tip",
                     "velocity_m_s": 2.5, "nearest_note": {"index": 0, "event": "SNARE", "instrument": "snare",
                                                           "time_s": 0.0, "offset_ms": 1.0}}
    assert second["nearest_note"]["index"] == 1 and second["velocity_m_s"] == 3.5
    assert evaluate.main([str(folder), "--json"]) == 0
    assert "impact_list" not in json.loads(capsys.readouterr().out)["files"][0]  # only when asked


def test_the_current_folders_plots_are_named_after_it(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    """``batteur evaluate . --plots P`` in a render folder wrote ``_pianoroll.png`` (the name of ``.`` is empty)."""
    monkeypatch.chdir(_write_render(tmp_path / "r1", _score(tmp_path / "groove.txt")))
    assert evaluate.main([".", "--plots", str(tmp_path / "P")]) == 0
    assert sorted(p.name for p in (tmp_path / "P").iterdir()) == ["r1_pianoroll.png", "r1_timing.png"]


def test_evaluate_plays_a_scores_kit_line_as_render_does(tmp_path: Path, renders: list[Path],
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    """A text score's ``kit`` line (render honours it unless --kit is given): ``--reuse`` takes a render on that kit
    and re-renders one on another; the kit given with --kit still wins (evaluate passed ``--kit default`` always)."""
    monkeypatch.chdir(tmp_path)
    score = Path("k.txt")
    score.write_text("kit double_pedal\n" + TINY)
    folder = _write_render(Path("R") / "k", score)
    report = json.loads((folder / "report.json").read_text())
    (folder / "report.json").write_text(json.dumps({**report, "kit": "double_pedal"}))
    assert evaluate.main(["k.txt", "--renders", "R", "--reuse", "--quiet"]) == 0
    assert renders == []  # reused: the render's kit is the score's
    assert evaluate.main(["k.txt", "--renders", "R", "--reuse", "--quiet", "--kit", "default"]) == 0
    assert renders == [folder]  # another kit asked: rendered again
