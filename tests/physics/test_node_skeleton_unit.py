"""The physics node started with ``--skeleton-bvh`` says once, at start, the skeleton's file, the unit it read it in
and the height of the performer its lengths imply (as ``batteur render``'s warning does): a skeleton read in the
wrong unit built a giant or a dwarf, and the node said nothing of the unit."""

from __future__ import annotations

import argparse
import logging
import re
from pathlib import Path

import pytest

from common.exit_status import InputError
from services.physics.bvh_motion import read_skeleton
from services.physics.node import PhysicsNodeSettings, make_core
from tests.render.test_render_skeleton_reach import _skeleton


def _started(bvh: Path, tmp_path: Path, caplog: pytest.LogCaptureFixture) -> list[str]:
    """What the node logs (batteur.physics, INFO) while making its core from ``bvh``, stopped right after by a kit
    file that is not there (the slow scene never built)."""
    settings = PhysicsNodeSettings(discovery=False, skeleton_bvh=str(bvh), kit=str(tmp_path / "no-kit.yaml"),
                                   height_m=1.6)
    with caplog.at_level(logging.INFO, logger="batteur.physics"), pytest.raises(InputError, match="no-kit.yaml"):
        make_core(settings, argparse.Namespace())
    return [r.getMessage() for r in caplog.records if r.name == "batteur.physics" and "skeleton" in r.getMessage()]


def test_the_node_says_the_unit_and_the_performer_of_its_skeleton(tmp_path: Path,
                                                                  caplog: pytest.LogCaptureFixture) -> None:
    bvh = _skeleton(tmp_path / "long.bvh", 36, 34, 42, 44)  # in centimetres
    stature = read_skeleton(bvh).stature_m
    assert stature is not None and 1.5 < stature < 2.2
    said = _started(bvh, tmp_path, caplog)
    # the longest offset, the shoulder's from the hips: (18, 45, 0) cm, 48.47
    assert said == [f"skeleton {bvh} read in centimetres: its longest offset, 48.47, is over 3; its lengths are a "
                    f"{stature:g} m performer's (the hands, feet and head and the body's place over the throne are "
                    "the 1.6 m drummer's of --height-m)"], said


def test_a_skeleton_in_millimetres_is_said_so(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    """The unit chosen when the first guess fits no performer (ee5d223) is the one said, with the reason."""
    bvh = _skeleton(tmp_path / "cm.bvh", 36, 34, 42, 44)
    mm = tmp_path / "mm.bvh"  # every offset ten times longer: millimetres
    mm.write_text(re.sub(r"OFFSET ([-\d. ]+)", lambda m: "OFFSET " + " ".join(
        f"{float(v) * 10:g}" for v in m.group(1).split()), bvh.read_text()))
    said = _started(mm, tmp_path, caplog)
    assert len(said) == 1 and said[0].startswith(f"skeleton {mm} read in millimetres: no performer has its lengths "
                                                 "in centimetres"), said
    assert f"a {read_skeleton(bvh).stature_m:g} m performer's" in said[0], said  # the same performer as in cm
