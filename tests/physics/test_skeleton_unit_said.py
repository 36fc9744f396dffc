"""The unit a skeleton was read in, said where it matters: ``--show-body`` (text and JSON) and the node's stature
warning.

Review of 6c221a4 (7 Dec): ``--show-body`` named the skeleton file but not the unit its lengths were read in (a
skeleton read in the wrong unit builds a giant or a dwarf), and the node's stature warning said
``--skeleton-units cm:`` when the unit came from ``BATTEUR_SKELETON_UNITS`` or a config file, where no such option
was given.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from services.physics.body_table import body_json, body_text
from services.physics.bvh_motion import read_skeleton, stature_warning
from tests.physics.test_skeleton_units_given import CHILD_SCALE, _bvh, _started


def test_the_stature_warning_names_the_setting_not_an_option(tmp_path: Path,
                                                              caplog: pytest.LogCaptureFixture) -> None:
    path = _bvh(tmp_path, CHILD_SCALE)
    said = _started(path, "cm", tmp_path, caplog)
    assert said[1:] == [f"skeleton units cm: {stature_warning(read_skeleton(path, 'cm'))}"], said


@pytest.mark.parametrize(("units", "unit", "words"), [
    ("cm", "cm", "centimetres: as given"), ("auto", "in", "inches: no performer has its lengths in centimetres")])
def test_show_body_says_the_unit_the_skeleton_was_read_in(tmp_path: Path, units: str, unit: str, words: str) -> None:
    from services.physics.core import PhysicsCore
    from services.physics.drummer import DrummerScene

    path = _bvh(tmp_path, CHILD_SCALE)
    core = PhysicsCore(scene="drummer", pose_rate_hz=0, skeleton_bvh=str(path), skeleton_units=units)
    try:
        assert isinstance(core.scene, DrummerScene)
        body = body_json(core.scene)
        text = body_text(core.scene)
    finally:
        core.close()
    assert (body["skeleton_bvh"], body["skeleton_unit"]) == (str(path), unit)
    assert body["skeleton_unit_why"] == read_skeleton(path, units).why
    assert f"; skeleton: {path} (read in {words}" in text.splitlines()[0], text.splitlines()[0]
