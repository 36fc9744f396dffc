"""``batteur render --skeleton-units {auto,m,cm,mm,in}``: the unit of the ``--skeleton-bvh`` file said by the user
(the physics node's option of the same name: tests/physics/test_skeleton_units_given.py).

Before: the unit was always guessed (the one making a 1.2-2.2 m performer): a 0.855 m character in centimetres was
rendered as a 2.17 m one in inches, and a 2.39 m one was refused, with no way to say the file's unit."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import pytest

from batteur import render
from tests.physics.test_skeleton_names_units import MIXAMO_JOINTS
from tests.physics.test_skeleton_units_given import CHILD_SCALE, TALL_SCALE, TINY_SCALE, _bvh


def _args(*argv: str) -> argparse.Namespace:
    return render.build_parser().parse_args(["s.mid", "-o", "out", *argv])


def test_the_option_and_its_refusal(capsys: pytest.CaptureFixture[str]) -> None:
    assert render.options_from(_args()).skeleton_units == "auto"
    assert render.options_from(_args("--skeleton-units", "mm")).skeleton_units == "mm"
    with pytest.raises(SystemExit) as exit_:
        _args("--skeleton-units", "ft")
    assert exit_.value.code == 2
    assert ("batteur render: error: argument --skeleton-units: invalid choice: 'ft' (choose from 'auto', 'm', 'cm', "
            "'mm', 'in')") in capsys.readouterr().err
    assert "--skeleton-units {auto,m,cm,mm,in}" in render.build_parser().format_help()


def test_the_warnings_say_the_unit_given_and_the_stature_outside_the_performers(tmp_path: Path) -> None:
    child = str(_bvh(tmp_path, CHILD_SCALE))
    said = render.options_in_vain(_args("--skeleton-bvh", child, "--skeleton-units", "cm"))
    assert len(said) == 2, said
    assert said[0].startswith("--skeleton-bvh without --height: ") and said[0].endswith(
        "give --height (the performer's, 1.2 to 2.2 m) to size them; the skeleton, a 0.855 m performer's, is read "
        "in centimetres: as given"), said
    assert said[1].startswith("--skeleton-units cm: the skeleton, read in centimetres as given, has a 0.855 m "
                              "performer's lengths, outside the 1.2 to 2.2 m"), said
    said = render.options_in_vain(_args("--skeleton-bvh", child, "--height", "1.5", "--skeleton-units", "cm"))
    assert len(said) == 2 and said[0].startswith("--height 1.5 with --skeleton-bvh") and said[1].startswith(
        "--skeleton-units cm: "), said
    auto = render.options_in_vain(_args("--skeleton-bvh", child))  # unchanged: inches, nothing more said
    assert len(auto) == 1 and "give --height 2.17 to size them as the skeleton's; the skeleton, a 2.17 m " \
        "performer's, is read in inches: no performer has its lengths in centimetres" in auto[0], auto
    assert render.options_in_vain(_args("--skeleton-units", "cm")) == [
        "--skeleton-units has no effect without --skeleton-bvh"]


def test_the_render_checks_and_reaches_with_the_unit_given(tmp_path: Path) -> None:
    child, tall, tiny = (_bvh(tmp_path, scale) for scale in (CHILD_SCALE, TALL_SCALE, TINY_SCALE))
    in_cm = render.RenderOptions(skeleton_bvh=child, skeleton_units="cm")
    render.check_options(in_cm)
    cm_limbs, auto_limbs = render.skeleton_limbs(in_cm), render.skeleton_limbs(render.RenderOptions(skeleton_bvh=child))
    assert cm_limbs is not None and auto_limbs is not None
    assert auto_limbs.arm_m - cm_limbs.arm_m == pytest.approx((0.14 + 0.13) * (2.54 - 1))  # the planner's reach
    with pytest.raises(ValueError, match="no other unit gives a performer's lengths either"):  # auto: refused
        render.check_options(render.RenderOptions(skeleton_bvh=tall))
    render.check_options(render.RenderOptions(skeleton_bvh=tall, skeleton_units="cm"))  # given: warned, rendered
    with pytest.raises(ValueError) as caught:  # read as 0.684 m, not 1.74 m: hips narrower than a body's
        render.check_options(render.RenderOptions(skeleton_bvh=tiny, skeleton_units="cm"))
    assert str(caught.value) == (f"--skeleton-bvh: {tiny}: segment hip_width length 0.072 m is implausible "
                                 "(expected 0.08 ... 0.5 m), measured from LeftUpLeg to RightUpLeg; its lengths are "
                                 f"a 0.684 m performer's, read in centimetres: as given. {MIXAMO_JOINTS}")


class _Built(Exception):
    """Raised by the stand-in physics core once it has the settings it was built with."""


def test_the_physics_core_gets_the_unit(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The drummer physics builds the body from the skeleton read in the unit given (the core's own reading of
    ``skeleton_units``: tests/physics/test_skeleton_units_given.py)."""
    from services.physics import core

    built: dict[str, Any] = {}

    def physics(**kwargs: Any) -> None:
        built.update(kwargs)
        raise _Built

    monkeypatch.setattr(core, "PhysicsCore", physics)
    opts = render.RenderOptions(skeleton_bvh=_bvh(tmp_path, CHILD_SCALE), skeleton_units="in")
    with pytest.raises(_Built):
        render.start_drummer(None, None, opts, 0.0)  # type: ignore[arg-type]
    assert (built["skeleton_bvh"], built["skeleton_units"]) == (str(opts.skeleton_bvh), "in")
