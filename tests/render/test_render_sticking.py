"""``--sticking`` of ``batteur render`` and ``batteur evaluate`` (``python -m common.score``'s since long; the two
commands had none) and the physics node's ``sticking`` setting: a roll is played with the pattern asked for, and
evaluate's ``--reuse`` does not take a render of another sticking for this one."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import pytest

from batteur import evaluate, render
from batteur.impact_log import COLUMNS
from common.kit import Limb, load_kit
from common.score.hands import Sticking

ROLL = "tempo 120\nmeter 4/4\nSN |xxxxxxxx........|\n"
"""Eight 16th notes on the snare (125 ms apart, under twice its 70 ms minTimeGap: a roll), then rests."""


def _roll_hands(tmp_path: Path, *argv: str) -> str:
    """The hands (L/R) ``batteur render ROLL -o out ARGV`` plays the roll with (its plan, without the physics)."""
    path = tmp_path / "roll.txt"
    path.write_text(ROLL, encoding="utf-8")
    opts = render.options_from(render.build_parser().parse_args([str(path), "-o", str(tmp_path / "out"), *argv]))
    _, assignment, _ = render.prepare(path, load_kit(), opts)
    return "".join("L" if n.limb == Limb.LEFT_HAND else "R" for n in assignment.notes)


@pytest.mark.parametrize(("sticking", "hands"), [("single", "LRLRLRLR"), ("double", "LLRRLLRR"),
                                                 ("paradiddle", "LRLLRLRR")])
def test_render_plays_a_roll_with_the_sticking_asked_for(tmp_path: Path, sticking: str, hands: str) -> None:
    """Led by the snare's hand (the left on the default kit); without the option the hand assignment chooses."""
    assert _roll_hands(tmp_path, "--sticking", sticking) == hands
    assert _roll_hands(tmp_path) == _roll_hands(tmp_path, "--sticking", "none")


def test_render_refuses_an_unknown_sticking(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_info:
        render.build_parser().parse_args(["s.txt", "-o", "out", "--sticking", "flam"])
    assert exit_info.value.code == 2
    assert "paradiddle" in capsys.readouterr().err  # the choices are named


def test_evaluate_renders_with_the_sticking_and_reuses_only_a_render_of_it(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "roll.txt"
    path.write_text(ROLL, encoding="utf-8")
    given: list[Any] = []
    monkeypatch.setattr(evaluate, "evaluate_scores", lambda paths, opts, *a, **k: given.append(opts) or [])
    evaluate.main([str(path), "--sticking", "double", "--quiet"])
    assert given[0].sticking == Sticking.DOUBLE
    folder = tmp_path / "render"
    folder.mkdir()
    (folder / "score.txt").write_text(ROLL, encoding="utf-8")
    (folder / "impacts.csv").write_text(",".join(COLUMNS) + "\n")
    report = {"scene": "drummer", "score": str(path), "kit": "default", "grip": "german", "nuance": "tenuto",
              "tempo_scale": 1.0, "control": "cartesian", "calibration": None, "drum_channels": None,
              "drum_map": None, "issues": [], "score_offset_s": 1.5, "duration_s": 4.0, "wall_time_s": 3.0,
              "cpu_time_s": 3.0, "real_time_factor": 1.3}
    (folder / "report.json").write_text(json.dumps(report), encoding="utf-8")  # before 8 Dec: no sticking
    assert evaluate.reusable(folder, path, render.RenderOptions())
    assert not evaluate.reusable(folder, path, render.RenderOptions(sticking=Sticking.DOUBLE))
    (folder / "report.json").write_text(json.dumps({**report, "sticking": "double"}), encoding="utf-8")
    assert evaluate.reusable(folder, path, render.RenderOptions(sticking=Sticking.DOUBLE))


def test_the_physics_node_plans_its_scores_with_its_sticking_setting(monkeypatch: pytest.MonkeyPatch) -> None:
    from services.physics.node import PhysicsNodeSettings, make_core

    monkeypatch.delenv("BATTEUR_STICKING", raising=False)
    monkeypatch.delenv("BATTEUR_CONFIG", raising=False)
    assert PhysicsNodeSettings(discovery=False).sticking == "none"
    core = make_core(PhysicsNodeSettings(discovery=False, sticking="paradiddle"), argparse.Namespace())
    try:
        assert core.score_player.sticking == Sticking.PARADIDDLE
    finally:
        core.close()
