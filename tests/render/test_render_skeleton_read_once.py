"""``batteur render --skeleton-bvh FILE`` works the skeleton's arms and legs out once and gives the same to the
kit's load warning and to the planner: it read the file for each (the two could differ if the file changed
between)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

import common.score.limbs
import services.physics.bvh_motion
from batteur import render
from tests.render.test_render_skeleton_reach import _skeleton

SCORE = "tempo 120\nmeter 4/4\nSN |x...|\n"


def test_the_skeletons_limbs_are_read_once_for_the_kit_warning_and_the_plan(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    worked_out: list[Any] = []  # what each reading of the skeleton's limbs gave
    warned_with: list[Any] = []  # the limbs the kit's load warning measured reach with
    planned_with: list[Any] = []  # the limbs the planner's reach came from
    read_limbs = services.physics.bvh_motion.skeleton_limb_lengths
    load_kit, distribute = render.load_kit, common.score.limbs.distribute

    def reading(*args: Any, **kwargs: Any) -> Any:
        worked_out.append(read_limbs(*args, **kwargs))
        return worked_out[-1]

    def loading(*args: Any, **kwargs: Any) -> Any:
        warned_with.append(kwargs.get("lengths"))
        return load_kit(*args, **kwargs)

    def distributing(*args: Any, **kwargs: Any) -> Any:
        planned_with.append(kwargs.get("lengths"))
        return distribute(*args, **kwargs)

    def simulated(*args: Any, **kwargs: Any) -> Any:
        raise render.RenderError("stopped before simulating")  # what is tested is done by then

    monkeypatch.setattr(services.physics.bvh_motion, "skeleton_limb_lengths", reading)
    monkeypatch.setattr(render, "load_kit", loading)
    monkeypatch.setattr(common.score.limbs, "distribute", distributing)
    monkeypatch.setattr(render, "run_score", simulated)
    score = tmp_path / "snare.txt"
    score.write_text(SCORE, encoding="utf-8")
    skeleton = _skeleton(tmp_path / "short.bvh", 20, 18, 25, 25)
    assert render.main([str(score), "-o", str(tmp_path / "out"), "--quiet", "--skeleton-bvh", str(skeleton)]) == 1
    assert capsys.readouterr().err.strip().endswith("stopped before simulating")
    assert len(worked_out) == 1  # was 2: once for the kit's warning, once for the plan
    assert worked_out[0] is not None
    assert warned_with == [worked_out[0]] and planned_with == [worked_out[0]]


def test_without_a_skeleton_neither_is_given_limbs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The height's reach (de Leva's table), as before: no limbs passed on."""
    planned_with: list[Any] = []
    distribute = common.score.limbs.distribute

    def distributing(*args: Any, **kwargs: Any) -> Any:
        planned_with.append(kwargs.get("lengths"))
        return distribute(*args, **kwargs)

    monkeypatch.setattr(common.score.limbs, "distribute", distributing)
    score = tmp_path / "snare.txt"
    score.write_text(SCORE, encoding="utf-8")
    render.prepare(score, render.load_kit("default"), render.RenderOptions())
    assert planned_with == [None]
