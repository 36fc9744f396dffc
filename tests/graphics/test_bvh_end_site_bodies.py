"""performance.bvh's End Sites are where physics puts the tips of the body it built: a foot's at its ball, a stick's
at its bead, for any body ``batteur render`` asks for.

The writer guessed them from the pose editor's snapshot of the 1.75 m drummer, the foot's scaled with the body's
shank. Physics places the ball of the foot from ``--height`` alone (``(0, -0.045 s + 0.72 foot, -0.08 s)``), while
``--skeleton-bvh`` gives the shank: with 0.52 m shanks the file's ball was 3.1 cm (19 %) past physics'. A body of
the table's proportions (``--height 1.5``) was and stays exact. Without the body's geometry (an export from the
viewer) the writer keeps its guess.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from batteur import render
from services.graphics.export import write_bvh
from services.graphics.export.bvh import DEFAULT_FACING, Y_UP
from services.graphics.poser import load_character, rest_poser
from services.graphics.sequence import PoseSequence

SCORE = "tempo 120\nmeter 4/4\nSN |x...|\nBD |x...|\n"
"""One snare and one bass drum note: a render long enough to write the BVH."""
TIPS = {"left_foot": "left_foot", "right_foot": "right_foot", "left_stick": "left_hand", "right_stick": "right_hand"}
"""Leaf link of the BVH -> the limb whose tip (physics' ball of the foot, stick tip) is its End Site."""


def _joint(name: str, offset: tuple[float, float, float], child: str, depth: int) -> str:
    pad = " " * depth
    inner = child or f"{pad} End Site\n{pad} {{\n{pad}  OFFSET 0 -5 0\n{pad} }}\n"
    return (f"{pad}JOINT {name}\n{pad}{{\n{pad} OFFSET {offset[0]} {offset[1]} {offset[2]}\n"
            f"{pad} CHANNELS 3 Zrotation Xrotation Yrotation\n{inner}{pad}}}\n")


def _skeleton(path: Path, shank_cm: float) -> Path:
    """A BVH (y up, centimetres, the usual joint names) of arms and legs hanging from the hips: the table's arms
    and thighs for 1.75 m, shanks ``shank_cm`` long."""
    joints = ""
    for side, x in (("Left", 18.0), ("Right", -18.0)):
        hand = _joint(f"{side}Hand", (0.0, -27.0, 0.0), "", 3)
        joints += _joint(f"{side}Arm", (x, 45.0, 0.0), _joint(f"{side}ForeArm", (0.0, -28.0, 0.0), hand, 2), 1)
        foot = _joint(f"{side}Foot", (0.0, -shank_cm, 0.0), "", 3)
        joints += _joint(f"{side}UpLeg", (x / 2, -5.0, 0.0), _joint(f"{side}Leg", (0.0, -42.0, 0.0), foot, 2), 1)
    path.write_text("HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 6 Xposition Yposition Zposition Zrotation "
                    "Xrotation Yrotation\n" + joints + "}\nMOTION\nFrames: 1\nFrame Time: 0.03\n"
                    + " ".join(["0"] * 42) + "\n", encoding="utf-8")
    return path


def _end_sites(path: Path) -> dict[str, np.ndarray]:
    """Leaf joint -> its End Site as written (file units and axes)."""
    lines = [line.strip() for line in path.read_text(encoding="utf-8").splitlines()]
    sites: dict[str, np.ndarray] = {}
    joint = ""
    for k, line in enumerate(lines):
        if line.startswith(("ROOT ", "JOINT ")):
            joint = line.split()[1]
        elif line == "End Site":
            sites[joint] = np.array([float(v) for v in lines[k + 2].split()[1:]])
    return sites


def _physics_tips(opts: render.RenderOptions) -> dict[str, np.ndarray]:
    """Leaf link -> where physics' drummer for ``opts`` has its limb's tip, metres in the link's frame (z up),
    measured on the simulated body (as the pose editor's snapshot is)."""
    from services.physics.core import PhysicsCore

    core = PhysicsCore(scene="drummer", height_m=opts.height_m, mass_kg=opts.mass_kg,
                       skeleton_bvh=None if opts.skeleton_bvh is None else str(opts.skeleton_bvh))
    try:
        body = core.scene.body  # type: ignore[attr-defined]
        tips = {}
        for link, limb in TIPS.items():
            pos, quat = body.link_pose(body.link_index[link])
            tip, _ = body.link_pose(body.tip_links[limb])
            tips[link] = Rotation.from_quat(quat).inv().apply(tip - pos)
        return tips
    finally:
        core.close()


@pytest.mark.parametrize("body", ["long shanks", "height 1.5"])
def test_the_end_sites_are_the_tips_of_the_body_physics_built(tmp_path: Path, body: str) -> None:
    if body == "long shanks":
        opts = render.RenderOptions(skeleton_bvh=_skeleton(tmp_path / "longshank.bvh", 52.0), settle_s=0.2,
                                    tail_s=0.2)
    else:
        opts = render.RenderOptions(height_m=1.5, settle_s=0.2, tail_s=0.2)
    score = tmp_path / "score.txt"
    score.write_text(SCORE, encoding="utf-8")
    render.render_score(score, tmp_path / "out", opts, quiet=True)
    written = _end_sites(tmp_path / "out" / "performance.bvh")
    for link, tip in _physics_tips(opts).items():
        # the file's 6 decimals: half a micrometre
        want = Y_UP[DEFAULT_FACING] @ tip  # the file's axes (render's default facing, +z)
        assert np.abs(written[link] - want).max() < 1e-6, (link, written[link], want)
    if body == "long shanks":  # the body physics built (and the file) has the skeleton's shanks
        lines = [line.strip() for line in (tmp_path / "out" / "performance.bvh").read_text().splitlines()]
        foot = lines[lines.index("JOINT left_foot") + 2].split()[1:]  # its OFFSET: the shank's length
        assert np.linalg.norm([float(v) for v in foot]) == pytest.approx(0.52, abs=1e-5)


def test_given_end_sites_are_written_as_given_and_the_others_guessed(tmp_path: Path) -> None:
    """The writer takes a mapping of leaf link -> End Site (metres, the link's frame, z up); leaves not in it keep
    the snapshot's guess (the viewer's exports, which do not know the body)."""
    poser = rest_poser()
    pose = poser.pose(poser.angles)
    sequence = PoseSequence(list(poser.names), np.arange(3) / 60.0, np.stack([pose] * 3))
    write_bvh(sequence, tmp_path / "guessed.bvh", rate_hz=60.0, scale=100.0)
    write_bvh(sequence, tmp_path / "given.bvh", rate_hz=60.0, scale=100.0,
              end_sites={"left_foot": (0.01, 0.2, -0.07)})
    guessed, given = _end_sites(tmp_path / "guessed.bvh"), _end_sites(tmp_path / "given.bvh")
    assert given["left_foot"] == pytest.approx([-1.0, -7.0, 20.0], abs=1e-6)  # (-x, z, y) in centimetres (+z)
    snapshot = Y_UP[DEFAULT_FACING] @ load_character().effectors["left_foot"][1] * 100.0
    assert guessed["left_foot"] == pytest.approx(snapshot, abs=2e-4)  # the rest pose's own shank: scale ~1
    assert {link: list(v) for link, v in given.items() if link != "left_foot"} == \
        {link: list(v) for link, v in guessed.items() if link != "left_foot"}
