"""``batteur rig --score FILE`` starts its services on the kit the score's ``kit`` line names, as ``batteur render``
plays it (``--kit`` given wins, as render's). The services were started on their default kit whatever the score
said: physics then warned in its log that the score's kit was not played, and the rig had no ``--kit`` to give.

Tested on the command lines the rig builds for its services (:func:`batteur.rig.plan_services`), no process
started."""

from __future__ import annotations

from pathlib import Path

import pytest

from batteur.rig import build_parser, plan_services
from common.score.events import ScoreError

GROOVE = "tempo 100\nmeter 4/4\nHH |x.x.x.x.|\nBD |x...x...|\n"


def _kits(tmp_path: Path, *argv: str) -> dict[str, list[str]]:
    """Role -> the values of ``--kit`` in its command line."""
    opts = build_parser().parse_args(["--no-discovery", *argv])
    kits = {}
    for plan in plan_services(opts, epoch=0.0):
        argv_ = plan.argv()
        kits[plan.role] = [argv_[i + 1] for i, a in enumerate(argv_) if a == "--kit"]
    return kits


def test_the_score_kit_line_is_every_service_kit(tmp_path: Path) -> None:
    score = tmp_path / "groove.txt"
    score.write_text("kit double_pedal\n" + GROOVE)
    kits = _kits(tmp_path, "--score", str(score))
    assert kits == {role: ["double_pedal"] for role in ("physics", "interaction", "sound", "graphics")}


def test_a_kit_file_the_score_names_is_taken_from_its_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    folder = tmp_path / "scores"
    folder.mkdir()
    kit = folder / "mine.yaml"
    kit.write_text((Path(__file__).resolve().parents[2] / "common" / "kits" / "default.yaml").read_text())
    (folder / "groove.txt").write_text("kit mine.yaml\n" + GROOVE)
    monkeypatch.chdir(tmp_path)  # a relative --score: the kit is still the one beside it, named in full
    kits = _kits(tmp_path, "--score", "scores/groove.txt", "--services", "physics,sound")
    assert kits == {"physics": [str(kit)], "sound": [str(kit)]}


def test_kit_given_wins_over_the_score_line_as_in_render(tmp_path: Path) -> None:
    score = tmp_path / "groove.txt"
    score.write_text("kit double_pedal\n" + GROOVE)
    kits = _kits(tmp_path, "--score", str(score), "--kit", "left_handed", "--services", "physics,interaction")
    assert kits == {"physics": ["left_handed"], "interaction": ["left_handed"]}


def test_no_kit_line_leaves_the_services_default(tmp_path: Path) -> None:
    score = tmp_path / "groove.txt"
    score.write_text(GROOVE)
    assert _kits(tmp_path, "--score", str(score), "--services", "physics,sound") == {"physics": [], "sound": []}


def test_a_kit_line_that_cannot_be_loaded_is_refused_before_any_service_starts(tmp_path: Path) -> None:
    score = tmp_path / "groove.txt"
    score.write_text("tempo 100\nkit nokit\nHH |x.x.x.x.|\n")
    with pytest.raises(ScoreError, match=r"groove.txt: line 2: kit 'nokit'"):
        _kits(tmp_path, "--score", str(score))
    with pytest.raises(ValueError, match="--kit nokit"):
        _kits(tmp_path, "--kit", "nokit")
