"""Mirroring a kit twice gives the kit back: a user mirroring a kit for a left-handed drummer and back (Kit.mirrored,
the viewer's kit editor) got a kit named ``...-mirrored-mirrored`` whose hit-point angles differed in their last
digit (-1.5708 became -1.5708000000000002), so its saved file differed from the kit's."""

from __future__ import annotations

import math
import random

import pytest

from common.kit import KITS_DIR, load_kit, mirrored_angle


@pytest.mark.parametrize("name", sorted(p.stem for p in KITS_DIR.glob("*.yaml")))
def test_mirroring_a_shipped_kit_twice_gives_it_back(name: str) -> None:
    kit = load_kit(name)
    once = kit.mirrored()
    assert once.name == f"{name}-mirrored" and once.handedness != kit.handedness
    assert once.mirrored() == kit  # the whole model, every number exactly, and the name


def test_the_shipped_left_handed_kit_and_the_default_kit_mirror_into_each_other() -> None:
    """left_handed.yaml is the default kit mirrored: mirroring it gives the default kit's numbers (the angles as
    default.yaml writes them, not one rounding off), and mirroring the default kit gives the file's."""
    default, left = load_kit("default"), load_kit("left_handed")
    assert default.mirrored() == left.model_copy(update={"name": "default-mirrored"})
    assert left.mirrored() == default.model_copy(update={"name": "left_handed-mirrored"})


def test_an_angle_written_with_up_to_12_decimals_comes_back_exactly() -> None:
    """Any angle a person writes (up to 12 decimals, within a turn either way) mirrors to the float nearest
    pi - theta, as it always did, and back to the written angle; the mirrored angle mirrors back to itself too."""
    rng = random.Random(7)
    for _ in range(20000):
        theta = round(rng.uniform(-2 * math.pi, 2 * math.pi), rng.randint(0, 12))
        mirrored = mirrored_angle(theta)
        assert mirrored == math.pi - theta
        assert mirrored_angle(mirrored) == theta, theta
        assert mirrored_angle(mirrored_angle(mirrored)) == mirrored
