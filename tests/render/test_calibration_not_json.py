"""A file that is not a calibration (a kit's YAML given to --calibration) is said in plain words, with what a
calibration file is and how one is made, not only Python's JSON message ("Expecting value: line 1 column 1 (char
0)")."""

from __future__ import annotations

from pathlib import Path

import pytest

from batteur.calibration import Calibration


def test_a_yaml_file_given_as_the_calibration_says_what_one_is(tmp_path: Path) -> None:
    path = tmp_path / "kit.yml"
    path.write_text("name: mine\nobjects: []\n")
    with pytest.raises(ValueError) as refused:
        Calibration.load(path)
    assert str(refused.value) == (
        f"{path}: not a calibration file (not JSON: expecting a value at line 1, column 1); a calibration file is "
        "the JSON `batteur evaluate --fit-calibration FILE` writes (timing offsets and velocity maps)")


def test_json_of_another_shape_says_what_one_is(tmp_path: Path) -> None:
    path = tmp_path / "cal.json"
    path.write_text('{"timing": {}}')
    with pytest.raises(ValueError) as refused:
        Calibration.load(path)
    assert "unknown keys ['timing']" in str(refused.value)
    assert str(refused.value).endswith("`batteur evaluate --fit-calibration FILE` writes (timing offsets and "
                                       "velocity maps)")
