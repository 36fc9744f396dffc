"""What a new user met with `batteur render`: a text score's `kit` line honoured (as `grip` and `nuance`),
options given in vain said, out-of-range values said as a range (not pydantic's words), --help naming what is
read, and --height beside --skeleton-bvh said once."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from batteur import render
from common.kit import load_kit
from common.score.events import ScoreError
from common.score.text import parse_text, read_score

ONE_BAR = "tempo 120\nmeter 4/4\nSN |x.x.|\n"


def _score(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "score.txt"
    path.write_text(text)
    return path


def test_a_text_score_names_its_kit_and_the_line() -> None:
    score = parse_text("title x\nkit double_pedal\n" + ONE_BAR)
    assert (score.kit, score.kit_line) == ("double_pedal", 2)
    assert parse_text(ONE_BAR).kit is None


def test_a_kit_line_without_a_name_is_refused() -> None:
    with pytest.raises(ScoreError, match="line 1: .*write kit NAME"):
        parse_text("kit\n" + ONE_BAR)


def test_the_score_kit_is_played_unless_kit_is_given(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    loaded: list[str] = []

    def spy(source: str, **kwargs: object) -> object:
        loaded.append(str(source))
        raise render.RenderError("stop here")  # only which kit is loaded matters

    monkeypatch.setattr(render, "load_kit", spy)
    path = _score(tmp_path, "kit double_pedal\n" + ONE_BAR)
    for argv, kit in (([], "double_pedal"), (["--kit", "left_handed"], "left_handed")):
        assert render.main([str(path), "-o", str(tmp_path / "out"), "--quiet", *argv]) == 1
        assert loaded[-1] == kit
    assert render.main([str(_score(tmp_path, ONE_BAR)), "-o", str(tmp_path / "out"), "--quiet"]) == 1
    assert loaded[-1] == "default"  # no kit line, no --kit: the default, as before


def test_the_score_kit_is_in_the_report(tmp_path: Path) -> None:
    out = tmp_path / "out"
    path = _score(tmp_path, "kit double_pedal\n" + ONE_BAR)
    assert render.main([str(path), "-o", str(out), "--quiet"]) == 0
    assert json.loads((out / "report.json").read_text())["kit"] == "double_pedal"


def test_an_unknown_kit_in_a_score_names_the_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _score(tmp_path, "tempo 120\nkit nosuchkit\nmeter 4/4\nSN |x.x.|\n")
    assert render.main([str(path), "-o", str(tmp_path / "out"), "--quiet"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{path}: line 2: kit 'nosuchkit': " in err[0] and "shipped kits: " in err[0], err
    assert not (tmp_path / "out").exists()


def test_a_kit_file_named_in_a_score_is_found_beside_it(tmp_path: Path) -> None:
    (tmp_path / "kits").mkdir()
    (tmp_path / "kits" / "mine.yaml").write_text((Path(render.__file__).parents[1] / "common" / "kits"
                                                  / "default.yaml").read_text())
    path = _score(tmp_path, "kit kits/mine.yaml\n" + ONE_BAR)
    score = read_score(path)
    opts = render.RenderOptions(kit=None).styled(score)
    assert opts.kit == str(tmp_path / "kits" / "mine.yaml")
    assert load_kit(opts.kit).name == load_kit("default").name
    assert render.file_kit(path) == opts.kit  # what a re-render (evaluate --reuse) would compare


def test_event_without_strikes_is_said_in_vain(capsys: pytest.CaptureFixture[str]) -> None:
    args = render.build_parser().parse_args(["s.txt", "-o", "out", "--event", "CRASH"])
    assert "--event has no effect without --strikes (a score's notes say what is struck)" in \
        render.options_in_vain(args)
    plain = render.build_parser().parse_args(["s.txt", "-o", "out"])
    assert not any("--event" in w for w in render.options_in_vain(plain))
    strikes = render.build_parser().parse_args(["--strikes", "0.25:3", "-o", "out", "--event", "CRASH"])
    assert not any("--event" in w for w in render.options_in_vain(strikes))


@pytest.mark.parametrize("argv, message", [
    (["--control-rate", "0"], "--control-rate 0: 50 to 1000 Hz"),
    (["--control-rate", "3000"], "--control-rate 3000: 50 to 1000 Hz"),
    (["--latency", "-1"], "--latency -1: 0 to "),
])
def test_out_of_range_values_are_said_as_ranges(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                 argv: list[str], message: str) -> None:
    path = _score(tmp_path, ONE_BAR)
    assert render.main([str(path), "-o", str(tmp_path / "out"), "--quiet", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert f"batteur render: error: {message}" in err and "Input should" not in err, err


def test_control_rates_up_to_the_physics_rate_are_taken() -> None:
    for rate in (50.0, 250.0, 1000.0):
        render.check_options(render.RenderOptions(control_rate_hz=rate))


def test_help_names_what_is_read_and_every_control() -> None:
    text = " ".join(render.build_parser().format_help().split())
    for suffix in (".mid", ".midi", ".smf", ".rmi"):
        assert suffix in text
    assert "MIDI header" in text
    for name in render.CONTROL_MODES:
        assert name in text.split("--control {")[-1].split("}", 1)[1]  # each choice explained, not only listed


def test_height_with_a_skeleton_is_said_once(tmp_path: Path) -> None:
    args = render.build_parser().parse_args(["s.txt", "-o", "out", "--height", "1.3", "--skeleton-bvh", "x.bvh"])
    said = [w for w in render.options_in_vain(args) if "--height" in w]
    assert len(said) == 1 and "--skeleton-bvh" in said[0] and "shoulders" in said[0] and "limbs" in said[0]
    alone = render.build_parser().parse_args(["s.txt", "-o", "out", "--skeleton-bvh", "x.bvh"])
    assert not any("--height" in w for w in render.options_in_vain(alone))


def test_the_default_height_given_with_a_skeleton_is_said_too() -> None:
    """``--height 1.75`` is the default's value: it was taken for no --height at all, and not said."""
    args = render.build_parser().parse_args(["s.txt", "-o", "out", "--height", "1.75", "--skeleton-bvh", "x.bvh"])
    said = [w for w in render.options_in_vain(args) if "--height" in w]
    assert len(said) == 1 and said[0].startswith("--height 1.75 with --skeleton-bvh: "), said
    strikes = render.build_parser().parse_args(["--strikes", "0.5:2", "-o", "out", "--height", "1.75"])
    assert "--height has no effect with --strikes (the strike scene has no drummer)" in \
        render.options_in_vain(strikes)


def test_no_height_is_the_default_drummer_s() -> None:
    from batteur import evaluate

    for argv in (["s.txt", "-o", "out"], ["s.txt", "-o", "out", "--skeleton-bvh", "x.bvh"]):
        assert render.options_from(render.build_parser().parse_args(argv)).height_m == render.STATURE_M == 1.75
    assert render.height_of(evaluate.build_parser().parse_args(["s.txt"])) == 1.75
    assert render.height_of(evaluate.build_parser().parse_args(["s.txt", "--height", "1.4"])) == 1.4
    help_text = " ".join(render.build_parser().format_help().split())
    assert ("the planner's reach (default 1.75; with --skeleton-bvh the skeleton gives the limbs and the reach, "
            "the height the rest)") in help_text
