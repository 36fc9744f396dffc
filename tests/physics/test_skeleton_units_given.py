"""``--skeleton-units {auto,m,cm,mm,in}`` (the physics node; ``batteur render``'s in tests/render): the unit of a
``--skeleton-bvh`` file said by the user, not guessed.

Before: the unit was always guessed from the stature (the one making a 1.2-2.2 m performer), so a child-sized or
stylised character in centimetres was read in inches (a 0.855 m one as a 2.17 m one, a 0.684 m one as a 1.74 m one)
and there was no way to say otherwise; a 2.39 m one was refused whatever its unit. With a unit given: no guess, the
stature said as before, one outside 1.2-2.2 m warned of with what it means for the drummer, not refused (proportions
no body has still are, saying the performer the unit makes)."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import pytest

from common.exit_status import InputError
from services.physics import node
from services.physics.anthropometry import SKELETON_UNITS, SkeletonUnits
from services.physics.bvh_motion import (
    METRES_PER_SKELETON_UNIT,
    read_skeleton,
    skeleton_limb_lengths,
    stature_warning,
    usable_segment_lengths,
)
from tests.physics.test_skeleton_names_units import MIXAMO, MIXAMO_JOINTS, skeleton

CHILD_SCALE = 0.5
""":func:`skeleton` at this scale, in centimetres: a 0.855 m performer (upper arms 14 cm), read as a 2.17 m one in
inches by the guess; its lengths are a body's."""
TINY_SCALE = 0.4
"""A 0.684 m performer in centimetres (1.74 m in inches): hips 7.2 cm apart, narrower than any body's (8 cm)."""
TALL_SCALE = 1.4
"""A 2.39 m performer in centimetres: no unit makes a performer, so the guess refuses it."""


def _bvh(tmp_path: Path, scale: float) -> Path:
    path = tmp_path / f"skeleton-{scale:g}.bvh"
    path.write_text(skeleton(MIXAMO, scale), encoding="utf-8")
    return path


def test_the_units_taken_are_the_readers() -> None:
    assert SKELETON_UNITS == ("auto", *METRES_PER_SKELETON_UNIT)


def test_a_child_sized_skeleton_in_centimetres_is_read_and_built_as_one(tmp_path: Path) -> None:
    path = _bvh(tmp_path, CHILD_SCALE)
    guessed = read_skeleton(path)
    assert (guessed.unit, guessed.stature_m, guessed.given) == ("in", 2.17, False)  # auto: unchanged
    assert stature_warning(guessed) is None
    given = read_skeleton(path, "cm")
    assert (given.unit, given.stature_m, given.given) == ("cm", 0.855, True)
    assert usable_segment_lengths(path, "cm") == pytest.approx(given.lengths_m)  # was: refused, 0.855 m
    assert given.lengths_m["upper_arm"] == pytest.approx(0.14)
    arms = {units: skeleton_limb_lengths(path, 1.75, 73.0, units).arm_m for units in ("cm", "auto")}  # the reach
    assert arms["auto"] - arms["cm"] == pytest.approx((0.14 + 0.13) * (2.54 - 1))  # upper arm, forearm: in vs cm
    said = stature_warning(given)
    assert said is not None and said.startswith(
        "the skeleton, read in centimetres as given, has a 0.855 m performer's lengths, outside the 1.2 to 2.2 m of "
        "the performers the kits are set for: the drummer gets its arms, legs, neck and trunk"), said
    assert said.endswith("its shorter arms and legs may not reach every instrument of a kit set for a performer (the "
                         "notes there are missed; the kit's reach warning names the instruments)"), said


def test_a_tall_skeleton_in_a_unit_given_is_warned_of_not_refused(tmp_path: Path) -> None:
    path = _bvh(tmp_path, TALL_SCALE)
    with pytest.raises(ValueError, match="no other unit gives a performer's lengths either"):  # auto: refused
        usable_segment_lengths(path)
    usable_segment_lengths(path, "cm")
    said = stature_warning(read_skeleton(path, "cm"))
    assert said is not None and "a 2.39 m performer's lengths" in said and said.endswith(
        "its longer arms and legs play a kit set for a shorter performer, cramped")


def test_a_skeleton_no_body_has_in_the_unit_given_says_the_performer_it_makes(tmp_path: Path) -> None:
    """The 0.684 m skeleton in centimetres is read as 0.684 m (not 1.74 m in inches); its hips are too narrow for
    the body, which is refused naming the unit given and the stature."""
    path = _bvh(tmp_path, TINY_SCALE)
    assert (read_skeleton(path).unit, read_skeleton(path).stature_m) == ("in", 1.74)
    assert read_skeleton(path, "cm").stature_m == 0.684
    with pytest.raises(ValueError) as caught:
        usable_segment_lengths(path, "cm")
    assert str(caught.value) == (f"{path}: segment hip_width length 0.072 m is implausible (expected 0.08 ... 0.5 m), "
                                 "measured from LeftUpLeg to RightUpLeg; its lengths are a 0.684 m performer's, read "
                                 f"in centimetres: as given. {MIXAMO_JOINTS}")


def _started(bvh: Path | None, units: SkeletonUnits, tmp_path: Path, caplog: pytest.LogCaptureFixture) -> list[str]:
    """What the node logs (batteur.physics, INFO and up) while making its core from ``bvh`` read in ``units``,
    stopped right after by a kit file that is not there (the slow scene never built)."""
    settings = node.PhysicsNodeSettings(discovery=False, skeleton_bvh=None if bvh is None else str(bvh),
                                        skeleton_units=units, kit=str(tmp_path / "no-kit.yaml"), height_m=1.6)
    with caplog.at_level(logging.INFO, logger="batteur.physics"), pytest.raises(InputError, match="no-kit.yaml"):
        node.make_core(settings, argparse.Namespace())
    return [r.getMessage() for r in caplog.records if r.name == "batteur.physics" and "skeleton" in r.getMessage()]


def test_the_node_reads_the_skeleton_in_the_unit_given_and_says_the_stature(tmp_path: Path,
                                                                          caplog: pytest.LogCaptureFixture) -> None:
    path = _bvh(tmp_path, CHILD_SCALE)
    said = _started(path, "cm", tmp_path, caplog)
    assert said[0] == (f"skeleton {path} read in centimetres: as given; its lengths are a 0.855 m performer's (the "
                       "hands, feet and head and the body's place over the throne are the 1.6 m drummer's of "
                       "--height-m)"), said
    assert said[1:] == [f"skeleton units cm: {stature_warning(read_skeleton(path, 'cm'))}"], said
    caplog.clear()
    said = _started(path, "auto", tmp_path, caplog)  # unchanged: inches, the stature in range, nothing warned
    assert len(said) == 1 and said[0].startswith(f"skeleton {path} read in inches: ") and "a 2.17 m performer's" \
        in said[0], said


def test_the_node_refuses_the_tiny_skeleton_saying_its_stature(tmp_path: Path) -> None:
    settings = node.PhysicsNodeSettings(discovery=False, skeleton_bvh=str(_bvh(tmp_path, TINY_SCALE)),
                                        skeleton_units="cm")
    with pytest.raises(InputError, match=r"its lengths are a 0\.684 m performer's, read in centimetres: as given"):
        node.make_core(settings, argparse.Namespace())


def test_the_node_says_units_without_a_skeleton_do_nothing(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    assert _started(None, "mm", tmp_path, caplog) == ["--skeleton-units has no effect without --skeleton-bvh"]


def test_the_node_takes_the_units_and_refuses_others(capsys: pytest.CaptureFixture[str]) -> None:
    assert node.main(["--skeleton-units", "in", "--show-settings"]) == 0
    assert '"skeleton_units": "in"' in capsys.readouterr().out
    assert node.main(["--skeleton-units", "ft", "--show-settings"]) == 2
    assert capsys.readouterr().err.strip().endswith(
        "error: invalid setting skeleton_units: must be 'auto', 'm', 'cm', 'mm' or 'in' (got 'ft') "
        "[--skeleton-units / BATTEUR_SKELETON_UNITS]")


def test_the_drummer_is_built_from_the_skeleton_in_the_unit_given(tmp_path: Path) -> None:
    """The physics core (the node's and the render's) builds its body from the lengths in the unit given."""
    from services.physics.core import PhysicsCore

    path = _bvh(tmp_path, CHILD_SCALE)
    for units, upper_arm_m in (("cm", 0.14), ("auto", 0.14 * 2.54)):
        core = PhysicsCore(scene="drummer", pose_rate_hz=0, skeleton_bvh=str(path), skeleton_units=units)
        try:
            assert core.scene.anthro.segments["upper_arm"].length_m == pytest.approx(upper_arm_m)  # type: ignore
        finally:
            core.close()
