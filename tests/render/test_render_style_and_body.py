"""What a user asks for reaches the render: a text score's `grip` and `nuance` directives (unless --grip/--nuance
say otherwise), the drummer's --height and --mass, and the BVH's --bvh-rate; evaluate's --reuse tells them apart."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from batteur import evaluate, render
from batteur.impact_log import COLUMNS
from common.gesture.plan import GesturePlan, Grip, LimbTrajectory, Nuance
from common.gesture.reach import pull_into_reach
from common.kit import Limb, load_kit
from tests.far_kits import china_at

STYLED = "grip french\nnuance staccato\ntempo 120\nmeter 4/4\nSN |x.x.|\n"
"""One bar, two snare notes, asking for the french grip and staccato."""
PLAIN = "tempo 120\nmeter 4/4\nSN |x.x.|\n"


def _score(tmp_path: Path, text: str = STYLED) -> Path:
    path = tmp_path / "styled.txt"
    path.write_text(text)
    return path


def _options(*argv: str) -> render.RenderOptions:
    return render.options_from(render.build_parser().parse_args(["s.txt", "-o", "out", *argv]))


def test_the_score_style_plans_unless_an_option_names_another(tmp_path: Path,
                                                              monkeypatch: pytest.MonkeyPatch) -> None:
    import common.gesture.planner as planner

    configs: list[Any] = []
    real = planner.plan_gestures

    def spy(assignment: Any, kit: Any, score: Any, config: Any, **kwargs: Any) -> GesturePlan:
        configs.append(config)
        return real(assignment, kit, score, config, **kwargs)

    monkeypatch.setattr(planner, "plan_gestures", spy)
    score, kit = _score(tmp_path), load_kit("default")
    given = _options()
    assert (given.grip, given.nuance) == (None, None)  # not given: the score's may win
    prepared, _, _ = render.prepare(score, kit, given)
    assert (configs[-1].grip, configs[-1].nuance) == (Grip.FRENCH, Nuance.STACCATO)
    assert (given.styled(prepared).grip, given.styled(prepared).nuance) == ("french", Nuance.STACCATO)
    render.prepare(score, kit, _options("--grip", "german"))  # the option wins; the nuance stays the score's
    assert (configs[-1].grip, configs[-1].nuance) == (Grip.GERMAN, Nuance.STACCATO)
    render.prepare(score, kit, _options("--tempo-scale", "2"))  # a faster score keeps its directives
    assert (configs[-1].grip, configs[-1].nuance) == (Grip.FRENCH, Nuance.STACCATO)
    render.prepare(_score(tmp_path, PLAIN), kit, given)  # a score without directives: the defaults, as before
    assert (configs[-1].grip, configs[-1].nuance) == (Grip.GERMAN, Nuance.TENUTO)


def test_a_styled_score_of_a_small_drummer_renders_as_asked(tmp_path: Path) -> None:
    out = tmp_path / "out"
    code = render.main([str(_score(tmp_path)), "-o", str(out), "--quiet", "--height", "1.4", "--mass", "40",
                        "--bvh-rate", "30"])
    assert code == 0
    report = json.loads((out / "report.json").read_text())
    assert (report["grip"], report["nuance"]) == ("french", "staccato")
    assert report["physics"]["grip"] == "french"  # the hands hold the grip the gestures were planned with
    assert (report["height_m"], report["mass_kg"]) == (1.4, 40.0)
    assert (report["physics"]["height_m"], report["physics"]["mass_kg"]) == (1.4, 40.0)
    assert report["impacts"] >= 1
    bvh = (out / "performance.bvh").read_text().splitlines()
    assert "Frame Time: 0.03333333" in bvh
    frames = int(next(line for line in bvh if line.startswith("Frames:")).split()[1])
    assert abs(frames / 30.0 - report["duration_s"]) < 1.0  # 30 frames a second of the performance


@pytest.mark.parametrize("argv, message", [(["--height", "1.1"], "--height 1.1: 1.2 to 2.2 m"),
                                           (["--mass", "200"], "--mass 200: 35 to 150 kg"),
                                           (["--bvh-rate", "0"], "--bvh-rate 0: 1 to 1000 Hz")])
def test_a_body_or_frame_rate_out_of_range_is_refused_before_anything_runs(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], message: str) -> None:
    out = tmp_path / "out"
    assert render.main([str(_score(tmp_path)), "-o", str(out), "--quiet", *argv]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_the_physics_pose_rate_follows_the_bvh_but_never_coarsens_the_video() -> None:
    assert render.physics_pose_rate(render.RenderOptions()) == 60.0
    assert render.physics_pose_rate(render.RenderOptions(pose_rate_hz=24.0)) == 60.0
    assert render.physics_pose_rate(render.RenderOptions(pose_rate_hz=120.0)) == 120.0
    assert render.physics_pose_rate(render.RenderOptions(pose_rate_hz=1000.0)) == render.MAX_PHYSICS_POSE_HZ


def _fake_render(folder: Path, score_text: str, **report: Any) -> Path:
    folder.mkdir(parents=True)
    (folder / "score.txt").write_text(score_text)
    (folder / "impacts.csv").write_text(",".join(COLUMNS) + "\n")
    base = {"scene": "drummer", "score": "styled.txt", "kit": "default", "grip": "german", "nuance": "tenuto",
            "tempo_scale": 1.0, "control": "cartesian", "calibration": None, "issues": []}
    (folder / "report.json").write_text(json.dumps({**base, **report}))
    return folder


def test_reuse_takes_only_a_render_with_the_style_and_body_asked_for(tmp_path: Path) -> None:
    score = _score(tmp_path)
    given = render.RenderOptions()
    # a render made before the directives were honoured (german, tenuto) is another performance
    assert not evaluate.reusable(_fake_render(tmp_path / "old", STYLED), score, given)
    styled = _fake_render(tmp_path / "styled", STYLED, grip="french", nuance="staccato")
    assert evaluate.reusable(styled, score, given)  # without a height in the report: the default drummer's
    assert not evaluate.reusable(styled, score, render.RenderOptions(grip="german"))
    assert not evaluate.reusable(styled, score, render.RenderOptions(height_m=1.4))
    small = _fake_render(tmp_path / "small", STYLED, grip="french", nuance="staccato", height_m=1.4, mass_kg=40.0)
    assert evaluate.reusable(small, score, render.RenderOptions(height_m=1.4, mass_kg=40.0))
    assert not evaluate.reusable(small, score, render.RenderOptions(height_m=1.4))


def test_evaluate_takes_the_body_and_tells_given_style_options_from_defaults() -> None:
    args = evaluate.build_parser().parse_args(["s.txt", "--height", "1.4", "--mass", "40"])
    assert (args.height, args.mass, args.grip, args.nuance) == (1.4, 40.0, None, None)
    assert render.style_from(evaluate.build_parser().parse_args(["s.txt", "--nuance", "legato"])) == (
        None, Nuance.LEGATO)


def test_knots_out_of_the_body_reach_are_pulled_in_not_the_whole_plan_refused() -> None:
    times = np.array([0.0, 0.5, 1.0])
    near, far = np.array([0.3, 0.4, 0.8]), np.array([2.0, 0.4, 0.8])
    traj = LimbTrajectory(Limb.RIGHT_HAND, times, np.array([near, far, near]), np.zeros((3, 3)))
    plan = GesturePlan(trajectories={Limb.RIGHT_HAND: traj}, strokes=[])
    root = np.array([0.1, 0.0, 1.1])
    reach = {"right_hand": (root, 1.2), "left_hand": (root, 1.2)}
    pulled, counts = pull_into_reach(plan, reach)
    assert counts == {"right_hand": 1}
    moved = pulled.trajectories[Limb.RIGHT_HAND].positions
    assert np.linalg.norm(moved[1] - root) <= 1.2 and np.allclose(moved[[0, 2]], [near, near])
    assert np.allclose(np.cross(moved[1] - root, far - root), 0.0)  # toward the root, along the same line
    same, none = pull_into_reach(plan, {"right_hand": (root, 3.0)})
    assert same is plan and none == {}


def test_an_instrument_out_of_the_body_reach_is_flagged_and_the_rest_rendered(tmp_path: Path) -> None:
    from common.gesture.plan import IssueReason

    kit = load_kit("default")
    far = kit.model_copy(update={"objects": [  # the china 0.95 m further right: 1.41 m from the right shoulder
        o.model_copy(update={"position": (o.position[0] + 0.9, o.position[1] + 0.3, o.position[2])})
        if o.id == "china" else o for o in kit.objects]})
    score = _score(tmp_path, "tempo 120\nSN |x.x.x.x.|\nCH |....x...|\n")
    _, _, plan = render.prepare(score, far, render.RenderOptions())
    assert [i.event.value for i in plan.issues if i.reason == IssueReason.UNREACHABLE] == ["CHINA"]
    assert "CHINA" not in [s.event.value for s in plan.strokes]  # the hand does not go there
    pulled: dict[str, int] = {}
    render.start_drummer(plan, far, render.RenderOptions(), pulled=pulled).close()
    assert pulled == {}
    # a plan made for a larger body than physics' (the default drummer's, played by a 1.40 m one) is pulled in
    edge = china_at(kit, 1.10)
    _, _, tall = render.prepare(score, edge, render.RenderOptions())
    render.start_drummer(tall, edge, render.RenderOptions(height_m=1.4), pulled=pulled).close()  # pulled, not refused
    assert set(pulled) == {"right_hand"}


def test_the_render_s_body_ranges_are_physics_own() -> None:
    """``--height``/``--mass`` are checked before the render (render.py keeps the bounds, not to load physics for
    a command line's check): they must be those physics' settings refuse beyond, and its defaults."""
    from annotated_types import Ge, Le

    from services.physics.core import PhysicsSettings

    def bounds(name: str) -> tuple[float, float]:
        meta = PhysicsSettings.model_fields[name].metadata
        return (next(m.ge for m in meta if isinstance(m, Ge)), next(m.le for m in meta if isinstance(m, Le)))

    assert bounds("height_m") == render.HEIGHT_RANGE_M and bounds("mass_kg") == render.MASS_RANGE_KG
    assert PhysicsSettings().height_m == render.RenderOptions().height_m
    assert PhysicsSettings().mass_kg == render.DEFAULT_MASS_KG
