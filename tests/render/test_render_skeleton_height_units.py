"""``batteur render --skeleton-bvh`` says at its start what the skeleton does not give and the unit it is read in.

Before: without ``--height`` the skeleton's limbs were silently put on the default 1.75 m drummer's hands, feet,
head and place over the throne (only ``--height`` given beside it was said), and the skeleton's unit was guessed in
silence."""

from __future__ import annotations

from pathlib import Path

from batteur import render
from tests.physics.test_skeleton_names_units import MIXAMO, skeleton


def _warnings(*argv: str) -> list[str]:
    return render.options_in_vain(render.build_parser().parse_args(["s.mid", "-o", "out", *argv]))


def test_a_skeleton_without_height_says_the_rest_is_the_default_drummer_s(tmp_path: Path) -> None:
    small = tmp_path / "small.bvh"
    small.write_text(skeleton(MIXAMO, 0.75 * 10), encoding="utf-8")  # a small performer, in millimetres
    said = [w for w in _warnings("--skeleton-bvh", str(small)) if "--skeleton-bvh" in w]
    assert len(said) == 1, said
    assert said[0].startswith("--skeleton-bvh without --height: the skeleton gives the limbs (arms, legs, neck, "), said
    assert "are the default 1.75 m drummer's: give --height 1.28 to size them as the skeleton's; the skeleton, a " \
           "1.28 m performer's, is read in millimetres: no performer has its lengths in centimetres" in said[0], said


def test_height_beside_a_skeleton_says_the_unit_too(tmp_path: Path) -> None:
    cm = tmp_path / "cm.bvh"
    cm.write_text(skeleton(MIXAMO), encoding="utf-8")
    said = [w for w in _warnings("--skeleton-bvh", str(cm), "--height", "1.6") if "--skeleton-bvh" in w]
    assert len(said) == 1 and said[0].startswith("--height 1.6 with --skeleton-bvh: the skeleton gives the limbs")
    assert said[0].endswith("; the skeleton, a 1.71 m performer's, is read in centimetres: its longest offset, 100, "
                            "is over 3"), said


def test_a_skeleton_that_cannot_be_read_is_left_to_its_error(tmp_path: Path) -> None:
    """Its error follows (exit 1): a warning about it before would only add noise; no skeleton: nothing said."""
    assert not [w for w in _warnings("--skeleton-bvh", str(tmp_path / "none.bvh")) if "skeleton" in w]
    assert not [w for w in _warnings("--skeleton-bvh", str(tmp_path)) if "skeleton" in w]
    assert _warnings() == []
