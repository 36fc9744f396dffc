"""With --skeleton-bvh the kit's load warning measures the skeleton's reach, as the planner does
(``render.skeleton_limbs``), and says it is a skeleton's: a short-armed skeleton is warned of a china the 1.75 m
drummer of the table reaches, a long-armed one is not warned of a china a 1.40 m one of the table does not reach."""

from __future__ import annotations

import logging
from pathlib import Path

import pytest

from batteur import render
from common.kit import load_kit, save_kit
from common.score.limbs import LimbLengths, unplayable_instruments
from tests.far_kits import china_at
from tests.render.test_render_skeleton_reach import _skeleton


def _warnings(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING and r.name == "common.kit"]


def _edge_kit(tmp_path: Path) -> Path:
    """The default kit with its china 1.10 m from the default drummer's right shoulder (reach 1.15 m)."""
    path = tmp_path / "edge.yaml"
    save_kit(china_at(load_kit("default"), 1.10), path)
    return path


def test_a_render_with_a_short_armed_skeleton_warns_of_the_china_by_its_reach(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    score = tmp_path / "snare.txt"
    score.write_text("tempo 120\nmeter 4/4\nSN |x...|\n")
    short = _skeleton(tmp_path / "short.bvh", 20, 18, 25, 25)  # arm 0.47 m with the table's hand (the table: 0.64)
    with caplog.at_level(logging.WARNING, logger="common.kit"):
        assert render.main([str(score), "-o", str(tmp_path / "out"), "--quiet", "--kit", str(_edge_kit(tmp_path)),
                            "--skeleton-bvh", str(short)]) == 0
    said = sorted(line.split(": ", 1)[1] for line in _warnings(caplog))  # was: none (the table's 1.75 m reach)
    assert len(said) == 2 and said[0].startswith("china: out of both hands' reach")
    assert "a skeleton's hand reaching 0.977 m" in said[0]  # 1.15 m less the table's arm, plus the skeleton's
    assert said[1].startswith("hihat_pedal: out of the left foot's reach") and "a skeleton's leg reaching" in said[1]


def test_a_long_armed_skeleton_is_not_warned_of_what_it_reaches(tmp_path: Path,
                                                              caplog: pytest.LogCaptureFixture) -> None:
    path = _edge_kit(tmp_path)
    long = render.skeleton_limbs(render.RenderOptions(height_m=1.4,
                                                      skeleton_bvh=_skeleton(tmp_path / "long.bvh", 36, 34, 42, 44)))
    assert long is not None
    with caplog.at_level(logging.WARNING, logger="common.kit"):
        load_kit(path, height_m=1.4)
        assert len(_warnings(caplog)) == 1  # the 1.40 m drummer of the table does not reach it
        caplog.clear()
        load_kit(path, height_m=1.4, lengths=long)
        assert _warnings(caplog) == []
    # a skeleton's legs name it too
    legless = LimbLengths(arm_m=0.64, leg_m=0.30)
    said = unplayable_instruments(load_kit("default"), lengths=legless)
    assert said and all("a skeleton's leg reaching" in line for line in said)
