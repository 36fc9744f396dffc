"""With --skeleton-bvh the planner's reach is the skeleton's arms and legs (physics builds the body from them), not
de Leva's for --height: a short-armed skeleton does not reach a china a 1.75 m drummer of the table reaches, a
long-armed one reaches a china a 1.40 m one of the table does not."""

from __future__ import annotations

from pathlib import Path

import pytest

from batteur import render
from common.gesture.plan import IssueReason
from common.kit import EventType, Kit, load_kit
from common.score.limbs import FOOT_REACH, REACH, foot_reach, hand_reach
from tests.far_kits import china_at

SCORE = "tempo 120\nmeter 4/4\nSN |x.x.x.x.|\nCH |....x...|\nHP |x.x.x.x.|\n"
"""Four snare notes, a china note and four hi-hat pedal chicks."""


def _joint(name: str, offset: tuple[float, float, float], child: str, depth: int) -> str:
    pad = " " * depth
    inner = child or f"{pad} End Site\n{pad} {{\n{pad}  OFFSET 0 -5 0\n{pad} }}\n"
    return (f"{pad}JOINT {name}\n{pad}{{\n{pad} OFFSET {offset[0]} {offset[1]} {offset[2]}\n"
            f"{pad} CHANNELS 3 Zrotation Xrotation Yrotation\n{inner}{pad}}}\n")


def _skeleton(path: Path, upper_arm_cm: float, forearm_cm: float, thigh_cm: float, shank_cm: float) -> Path:
    """A BVH of arms and legs hanging down from the hips (y up, centimetres): shoulders 0.36 m apart, 0.45 m
    above the hips, 0.18 m apart."""
    joints = ""
    for side, x in (("Left", 18.0), ("Right", -18.0)):
        hand = _joint(f"{side}Hand", (0.0, -forearm_cm, 0.0), "", 3)
        joints += _joint(f"{side}Arm", (x, 45.0, 0.0), _joint(f"{side}ForeArm", (0.0, -upper_arm_cm, 0.0), hand, 2), 1)
        foot = _joint(f"{side}Foot", (0.0, -shank_cm, 0.0), "", 3)
        joints += _joint(f"{side}UpLeg", (x / 2, -5.0, 0.0), _joint(f"{side}Leg", (0.0, -thigh_cm, 0.0), foot, 2), 1)
    path.write_text("HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 6 Xposition Yposition Zposition Zrotation "
                    "Xrotation Yrotation\n" + joints + "}\nMOTION\nFrames: 1\nFrame Time: 0.03\n"
                    + " ".join(["0"] * 42) + "\n", encoding="utf-8")
    return path


def _flagged(tmp_path: Path, kit: Kit, **options: object) -> list[EventType]:
    score = tmp_path / "score.txt"
    score.write_text(SCORE)
    _, assignment, _ = render.prepare(score, kit, render.RenderOptions(**options))  # type: ignore[arg-type]
    return sorted({i.event for i in assignment.issues if i.reason == IssueReason.UNREACHABLE and i.event})


def test_the_planners_reach_follows_the_skeletons_arms_and_legs(tmp_path: Path) -> None:
    edge = china_at(load_kit("default"), 1.10)  # 1.10 m from the default shoulder
    short = _skeleton(tmp_path / "short.bvh", 20, 18, 25, 25)  # the table's 28 + 27 cm arm, 42 + 44 cm leg
    lengths = render.skeleton_limbs(render.RenderOptions(skeleton_bvh=short))
    assert lengths is not None
    assert hand_reach(1.75, lengths) == pytest.approx(REACH - 0.640 + 0.20 + 0.18 + 0.087, abs=0.002)
    assert foot_reach(1.75, lengths) == pytest.approx(FOOT_REACH - 0.86 + 0.50, abs=0.002)
    assert _flagged(tmp_path, edge) == []
    assert _flagged(tmp_path, edge, skeleton_bvh=short) == [EventType.CHINA, EventType.HIHATPEDAL]  # was: none
    long = _skeleton(tmp_path / "long.bvh", 36, 34, 42, 44)
    assert _flagged(tmp_path, edge, height_m=1.4) == [EventType.CHINA]
    assert _flagged(tmp_path, edge, height_m=1.4, skeleton_bvh=long) == []  # was: the china, as the height's
    assert render.skeleton_limbs(render.RenderOptions()) is None
