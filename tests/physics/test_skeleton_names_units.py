"""An animator's own skeleton (``--skeleton-bvh``, ``--limits-from``): Blender's and Unreal's joint names, side
suffixes, the file's unit and what is said about them.

Before: Blender's metarig names (upper_arm.L, shin.L, spine.001) and Unreal's mannequin's (upperarm_l, calf_l,
neck_01) were refused ("no arm, leg or trunk joints found by their usual BVH names", naming neither the file's
names nor those known); a skeleton in millimetres or inches failed on an unrounded length ("segment upper_arm
length 2.8000000000000007 m is implausible") without saying it had been read in centimetres; a still T-pose clip
printed scipy's raw "UserWarning: Gimbal lock detected"."""

from __future__ import annotations

import logging
import warnings
from pathlib import Path

import pytest

from common.gesture.bvh import BvhError, read_bvh
from services.physics import mocap
from services.physics.bvh_motion import (
    NAME_FAMILIES,
    bvh_segment_lengths,
    load_bvh_clip,
    map_segments,
    read_skeleton,
    skeleton_stature,
    usable_segment_lengths,
)
from services.physics.limits import limits_from_clips

MIXAMO = {"hips": "Hips", "spine": "Spine", "spine1": "Spine1", "chest": "Spine2", "neck": "Neck", "head": "Head",
          "clavicle": "{Side}Shoulder", "upper_arm": "{Side}Arm", "forearm": "{Side}ForeArm", "hand": "{Side}Hand",
          "thigh": "{Side}UpLeg", "shank": "{Side}Leg", "foot": "{Side}Foot"}
BLENDER = {"hips": "spine", "spine": "spine.001", "spine1": "spine.002", "chest": "spine.003", "neck": "spine.004",
           "head": "spine.006", "clavicle": "shoulder.{S}", "upper_arm": "upper_arm.{S}", "forearm": "forearm.{S}",
           "hand": "hand.{S}", "thigh": "thigh.{S}", "shank": "shin.{S}", "foot": "foot.{S}"}
UNREAL = {"hips": "pelvis", "spine": "spine_01", "spine1": "spine_02", "chest": "spine_03", "neck": "neck_01",
          "head": "head", "clavicle": "clavicle_{s}", "upper_arm": "upperarm_{s}", "forearm": "lowerarm_{s}",
          "hand": "hand_{s}", "thigh": "thigh_{s}", "shank": "calf_{s}", "foot": "foot_{s}"}

OURS = {"hips": "pelvis", "spine": "abdomen", "chest": "thorax", "neck": "neck", "head": "head",
        **{k: k for k in ("clavicle", "upper_arm", "forearm", "hand", "thigh", "shank", "foot")}}
"""Our link each joint of the test skeleton stands for (its spine1 is folded into the rotations)."""


def skeleton(names: dict[str, str], scale: float = 1.0, frames: int = 2, extra: str = "") -> str:
    """A T-pose BVH (y up, centimetres times ``scale``) with ``names`` (``{Side}``: Left/Right, ``{S}``: L/R,
    ``{s}``: l/r), its frames all the rest pose; ``extra``: a joint's block put in the left forearm."""
    def name(key: str, side: str = "") -> str:
        return names[key].format(Side=side, S=side[:1], s=side[:1].lower())

    def joint(key: str, offset: tuple[float, float, float], inner: str, side: str = "") -> str:
        x, y, z = (v * scale for v in offset)
        ex, ey, ez = (5 * v / max(abs(w) for w in (x, y, z)) for v in (x, y, z))  # on along the joint's offset
        return (f"JOINT {name(key, side)}\n{{\nOFFSET {x:g} {y:g} {z:g}\nCHANNELS 3 Zrotation Xrotation Yrotation\n"
                f"{inner or f'End Site {{ OFFSET {ex:g} {ey:g} {ez:g} }}'}\n}}\n")

    arms = legs = ""
    for side, x in (("Left", 1), ("Right", -1)):
        hand = joint("hand", (26 * x, 0, 0), "", side)
        arms += joint("clavicle", (6 * x, 10, 0), joint("upper_arm", (12 * x, 0, 0), joint(
            "forearm", (28 * x, 0, 0), hand + (extra if side == "Left" else ""), side), side), side)
        legs += joint("thigh", (9 * x, -5, 0), joint("shank", (0, -45, 0), joint("foot", (0, -42, 0), "", side),
                                                     side), side)
    head = joint("head", (0, 10, 0), "")
    chest = joint("chest", (0, 14, 0), joint("neck", (0, 15, 0), head) + arms)
    hierarchy = (f"HIERARCHY\nROOT {names['hips']}\n{{\nOFFSET 0 {100 * scale:g} 0\nCHANNELS 6 Xposition Yposition "
                 f"Zposition Zrotation Xrotation Yrotation\n"
                 + joint("spine", (0, 10, 0), joint("spine1", (0, 12, 0), chest)) + legs + "}\n")
    channels = 6 + 3 * (hierarchy.count("JOINT"))
    return hierarchy + f"MOTION\nFrames: {frames}\nFrame Time: 0.033333\n" + ("0 " * channels + "\n") * frames


def _file(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize("names", [BLENDER, UNREAL], ids=["blender", "unreal"])
def test_blender_and_unreal_names_are_found(tmp_path: Path, names: dict[str, str]) -> None:
    mixamo = _file(tmp_path, "mixamo.bvh", skeleton(MIXAMO))
    theirs = _file(tmp_path, "theirs.bvh", skeleton(names))
    bvh = read_bvh(theirs)
    found = {bvh.joints[i].name: link for link, i in map_segments(bvh).items()}
    expected = {names[key]: link for key, link in OURS.items() if "{" not in names[key]}
    expected.update({names[key].format(Side=side, S=side[0], s=side[0].lower()): f"{side.lower()}_{link}"
                     for key, link in OURS.items() if "{" in names[key] for side in ("Left", "Right")})
    assert found == expected
    assert usable_segment_lengths(theirs) == usable_segment_lengths(mixamo)
    clip = load_bvh_clip(theirs)  # --limits-from: the same joints driven as from Mixamo's names
    assert set(clip.rotations) == set(load_bvh_clip(mixamo).rotations)


def test_side_suffixes_in_any_spelling(tmp_path: Path) -> None:
    names = {**MIXAMO, "upper_arm": "UpperArm-{S}", "forearm": "forearm_{S}", "hand": "Hand_{S}",
             "thigh": "DEF-thigh.{S}", "shank": "shin_{s}"}
    bvh = read_bvh(_file(tmp_path, "mixed.bvh", skeleton(names)))
    found = {bvh.joints[i].name for i in map_segments(bvh).values()}
    assert {"UpperArm-L", "forearm_R", "DEF-thigh.L", "shin_r"} <= found


def test_two_joints_for_one_link_are_said_not_guessed(tmp_path: Path) -> None:
    """hand.L beside LeftHand (both the left hand by name): the first was taken, silently."""
    twin = "JOINT LeftHand\n{\nOFFSET 26 0 0\nCHANNELS 3 Zrotation Xrotation Yrotation\nEnd Site { OFFSET 5 0 0 }\n}\n"
    path = _file(tmp_path, "twins.bvh", skeleton(BLENDER, extra=twin))
    with pytest.raises(BvhError, match=r"twins\.bvh: joints 'hand\.L' and 'LeftHand' could each be the left hand: "
                                       r"rename or remove all but one"):
        usable_segment_lengths(path)
    with pytest.raises(BvhError, match="could each be the left hand"):
        load_bvh_clip(path)


def test_no_joint_found_lists_its_names_and_the_known_ones(tmp_path: Path) -> None:
    names = {key: f"bone{k}" + ("{S}" if "{" in value else "") for k, (key, value) in enumerate(MIXAMO.items())}
    path = _file(tmp_path, "anon.bvh", skeleton(names))
    with pytest.raises(BvhError) as caught:
        usable_segment_lengths(path)
    said = str(caught.value)
    assert said.startswith(f"{path}: no arm, leg or trunk joints found by their usual BVH names: its joints are "
                           "bone0, bone1, bone2, bone3, bone4, bone5, bone6L, bone7L, ... (20 joints)"), said
    for family, _ in NAME_FAMILIES:
        assert family in said
    for example in ("upper_arm.L", "upperarm_l", "LeftForeArm", "lShldr"):
        assert example in said


@pytest.mark.parametrize(("scale", "unit"), [(1.0, "cm"), (0.01, "m"), (10.0, "mm"), (1 / 2.54, "in")])
def test_the_unit_is_found_and_said(tmp_path: Path, scale: float, unit: str) -> None:
    """A skeleton in millimetres was read as centimetres (2.8 m upper arms), one in inches too (7 cm between the
    hips): refused, though only one unit makes it a performer."""
    cm = bvh_segment_lengths(_file(tmp_path, "cm.bvh", skeleton(MIXAMO)))
    path = _file(tmp_path, f"{unit}.bvh", skeleton(MIXAMO, scale))
    reading = read_skeleton(path)
    assert reading.unit == unit
    assert reading.lengths_m == pytest.approx(cm, rel=1e-5)
    assert usable_segment_lengths(path) == pytest.approx(cm, rel=1e-5)
    assert bvh_segment_lengths(path) == pytest.approx(cm, rel=1e-5)  # what the physics body is built from
    if unit in ("mm", "in"):  # said: not the first guess, and why
        assert reading.unit_words.startswith(f"{'millimetres' if unit == 'mm' else 'inches'}: no performer has its "
                                             "lengths in centimetres, the first guess (its longest offset, ")
    else:
        assert reading.why.startswith("its longest offset, ")
    assert read_skeleton(path, units="cm").lengths_m == pytest.approx(
        {k: v * scale for k, v in cm.items()}, rel=1e-5)  # a unit given is taken as it is


def test_a_skeleton_no_unit_fits_names_the_unit_and_rounds(tmp_path: Path) -> None:
    """Arms 4 times too long for the body in any unit: the error says which unit it was read in, 3 digits."""
    names = dict(MIXAMO)
    text = skeleton(names).replace("OFFSET 28 0 0", "OFFSET 168.1 0 0").replace("OFFSET -28 0 0", "OFFSET -168.1 0 0")
    path = _file(tmp_path, "long.bvh", text)
    with pytest.raises(BvhError) as caught:
        usable_segment_lengths(path)
    assert str(caught.value) == (
        f"{path}: segment upper_arm length 1.68 m is implausible (expected 0.01 ... 1.5 m), measured from LeftArm to "
        "LeftForeArm and RightArm to RightForeArm, read in centimetres: its longest offset, 168.1, is over 3; no other "
        "unit gives a performer's lengths either: in metres a 265 m performer's, in millimetres a 0.265 m "
        f"performer's, in inches a 6.72 m performer's (a performer is 1.2 to 2.2 m tall). {MIXAMO_JOINTS}")


FULL_M = 1.71
"""The stature of :func:`skeleton` at scale 1 (centimetres)."""
MIXAMO_JOINTS = (
    "The lengths were measured between these joints, found by name (a joint named otherwise is taken for another "
    "segment or not found): upper arm LeftArm to LeftForeArm and RightArm to RightForeArm; forearm LeftForeArm to "
    "LeftHand and RightForeArm to RightHand; thigh LeftUpLeg to LeftLeg and RightUpLeg to RightLeg; shank LeftLeg to "
    "LeftFoot and RightLeg to RightFoot; neck Neck to Head; hip width LeftUpLeg to RightUpLeg; shoulder height the "
    "hips (LeftUpLeg and RightUpLeg) up to the shoulders (LeftArm and RightArm); shoulder width LeftArm to RightArm")
"""What a refusal of a :func:`skeleton` of :data:`MIXAMO`'s names ends with: the joints each length was measured
between."""


@pytest.mark.parametrize("tall_m", [1.3, 1.95, 2.05, 2.2])
def test_a_tall_performer_in_inches_is_read_in_inches(tmp_path: Path, tall_m: float) -> None:
    """A 1.95-2.2 m skeleton in inches was read as a 0.77-0.87 m one in centimetres: only a skeleton no body had
    in the first guess was tried in other units, and a body's lengths allowed statures far below a performer's."""
    path = _file(tmp_path, "tall.bvh", skeleton(MIXAMO, tall_m / 2.54 / FULL_M))
    reading = read_skeleton(path)
    assert (reading.unit, reading.stature_m) == ("in", pytest.approx(tall_m, abs=0.01))
    assert reading.fits
    assert reading.why.startswith("no performer has its lengths in centimetres, the first guess (its longest "
                                  f"offset, {100 * tall_m / 2.54 / FULL_M:.4g}, is over 3): "), reading.why
    if tall_m > 1.9:  # each length a body's in centimetres: the stature says why not
        assert reading.why.endswith(f"its lengths are a {tall_m / 2.54:.3g} m performer's, not 1.2 to 2.2 m tall"), \
            reading.why
    assert usable_segment_lengths(path) == pytest.approx(reading.lengths_m)


def test_a_skeleton_whose_stature_no_unit_makes_a_performers_is_refused_with_each_units(tmp_path: Path) -> None:
    """1.11 m in centimetres, 2.82 m in inches: no performer's (1.2 ... 2.2 m) in any unit. It was built as a
    1.11 m body (each length within a body's bounds); a 0.68 m one was read in inches, a 0.86 m one in centimetres."""
    path = _file(tmp_path, "small.bvh", skeleton(MIXAMO, 0.65))
    reading = read_skeleton(path)
    assert (reading.unit, reading.fits) == ("cm", False)
    with pytest.raises(BvhError) as caught:
        usable_segment_lengths(path)
    assert str(caught.value) == (
        f"{path}: its lengths are a 1.11 m performer's, not 1.2 to 2.2 m tall, read in centimetres: its longest "
        "offset, 65, is over 3; no other unit gives a performer's lengths either: in metres a 111 m performer's, in "
        f"millimetres a 0.111 m performer's, in inches a 2.82 m performer's (a performer is 1.2 to 2.2 m tall). "
        f"{MIXAMO_JOINTS}")
    for scale in (0.4, 0.5):  # the one unit that gives a performer, whatever the first guess's body allowed
        assert read_skeleton(_file(tmp_path, f"{scale}.bvh", skeleton(MIXAMO, scale))).unit == "in"


def test_the_stature_range_is_the_performers() -> None:
    from batteur.render import HEIGHT_RANGE_M as RENDER_RANGE
    from services.physics.bvh_motion import STATURE_RANGE_M
    from services.physics.node import HEIGHT_RANGE_M

    assert STATURE_RANGE_M == HEIGHT_RANGE_M == RENDER_RANGE


def _rigify(names: dict[str, str]) -> str:
    """:func:`skeleton` as a Rigify export: every bone ``DEF-``, under a floor bone ``root`` at the origin."""
    head, motion = skeleton(names).split("MOTION", 1)
    lines = head.splitlines()
    at = next(i for i, line in enumerate(lines) if line.startswith("ROOT"))
    hips = lines[at].split()[1]
    lines = [*lines[:at], "ROOT root", "{", "OFFSET 0 0 0",
             "CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation", f"JOINT DEF-{hips}",
             *lines[at + 1:], "}"]
    text = "\n".join(line.replace("JOINT ", "JOINT DEF-") if line.startswith("JOINT ") and "DEF-" not in line
                     else line for line in lines)
    frames = [("0 0 0 0 0 0 " + line if line[:1].isdigit() else line) for line in motion.splitlines()]
    return text + "\nMOTION" + "\n".join(frames) + "\n"


def test_a_rigify_export_has_its_hips_not_its_floor_bone_for_the_pelvis(tmp_path: Path) -> None:
    """``root`` above ``DEF-spine``: the pelvis was the floor bone, the abdomen the hips (DEF-spine)."""
    path = _file(tmp_path, "rigify.bvh", _rigify(BLENDER))
    bvh = read_bvh(path)
    central = {link: bvh.joints[i].name for link, i in map_segments(bvh).items()
               if link in ("pelvis", "abdomen", "thorax", "neck", "head")}
    assert central == {"pelvis": "DEF-spine", "abdomen": "DEF-spine.001", "thorax": "DEF-spine.003",
                       "neck": "DEF-spine.004", "head": "DEF-spine.006"}
    metarig = _file(tmp_path, "metarig.bvh", skeleton(BLENDER))
    assert usable_segment_lengths(path) == pytest.approx(usable_segment_lengths(metarig))
    assert set(load_bvh_clip(path).rotations) == set(load_bvh_clip(metarig).rotations)
    unreal = read_bvh(_file(tmp_path, "unreal.bvh", _rigify(UNREAL)))  # no Blender chain: its pelvis by name
    assert unreal.joints[map_segments(unreal)["pelvis"]].name == "DEF-pelvis"


def test_the_stature_of_a_skeleton(tmp_path: Path) -> None:
    full = read_skeleton(_file(tmp_path, "full.bvh", skeleton(MIXAMO))).stature_m
    small = read_skeleton(_file(tmp_path, "small.bvh", skeleton(MIXAMO, 0.75))).stature_m
    assert full is not None and small is not None
    assert 1.6 < full < 1.8  # 28 cm upper arms, 45 cm thighs: about de Leva's 1.75 m performer
    assert small == pytest.approx(0.75 * full, abs=0.01)
    from services.physics.anthropometry import anthropometry

    table = anthropometry(1.62).segments
    assert skeleton_stature({k: table[k].length_m for k in ("upper_arm", "forearm", "thigh", "shank")}) == 1.62
    assert skeleton_stature({}) is None


def test_a_still_t_pose_clip_says_its_gimbal_lock_and_no_motion(tmp_path: Path,
                                                                 caplog: pytest.LogCaptureFixture) -> None:
    """--limits-from a T-pose held still: scipy's "UserWarning: Gimbal lock detected" (mocap.py) was printed raw,
    naming neither clip nor joint, and the clip's telling nothing was not said. Both notes name the clip's file as
    given (the gimbal lock's named its stem, ``tpose``, until 7 Dec)."""
    path = _file(tmp_path, "tpose.bvh", skeleton(MIXAMO, frames=3))
    getattr(mocap, "_GIMBAL_SAID", set()).clear()  # said once per process: this test's clip not yet
    with warnings.catch_warnings(), caplog.at_level(logging.WARNING, logger="batteur.physics.limits"):
        warnings.simplefilter("error")  # any warning left raw fails
        clip = load_bvh_clip(path)
        limits_from_clips([clip])
        limits_from_clips([clip])  # said once
    said = [r.getMessage() for r in caplog.records]
    assert said[0] == (f"clip {path} has no motion (its 3 frames hold one pose): it tells no range, so its joints "
                       "keep their anatomical limits (beside other clips it only adds that pose)")
    locked = [s for s in said if "gimbal lock" in s]
    assert locked == [f"clip {path}: joint {side}_shoulder is at gimbal lock (its y angle at 90 degrees) in 3 of 3 "
                      "frames: its x and z angles cannot be told apart there; the whole turn was given to x (z 0) for "
                      "its limits" for side in ("left", "right")]


def test_two_clips_of_one_name_in_two_folders_each_say_their_gimbal_lock(tmp_path: Path,
                                                                         caplog: pytest.LogCaptureFixture,
                                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """The note was kept per clip name for the whole process: a second tpose.bvh in another folder said nothing.
    Each note names its file as given (``a/tpose.bvh``): until 7 Dec both said ``clip tpose``, which could not be
    told apart."""
    getattr(mocap, "_GIMBAL_SAID", set()).clear()
    monkeypatch.chdir(tmp_path)
    paths = []
    for folder in ("a", "b"):
        (tmp_path / folder).mkdir()
        _file(tmp_path / folder, "tpose.bvh", skeleton(MIXAMO, frames=3))
        paths.append(f"{folder}/tpose.bvh")  # relative, as typed after --limits-from
    with warnings.catch_warnings(), caplog.at_level(logging.WARNING, logger="batteur.physics.limits"):
        warnings.simplefilter("error")
        for path in paths:
            limits_from_clips([load_bvh_clip(path), load_bvh_clip(path)])  # each file's said once
    locked = [r.getMessage() for r in caplog.records if "gimbal lock" in r.getMessage()]
    assert [s.split(" is at")[0] for s in locked] == [f"clip {folder}/tpose.bvh: joint {side}_shoulder"
                                                      for folder in ("a", "b") for side in ("left", "right")], locked


def test_a_shipped_deepmimic_clip_is_named_by_its_name_a_file_by_its_path(tmp_path: Path) -> None:
    """The notes name a clip by its ``source``: a shipped clip's name as given (not pybullet_data's path), a clip
    file's path as given (not its stem, one for two folders' files)."""
    assert mocap.load_deepmimic("punch").source == "punch"
    copy = tmp_path / "mine" / "humanoid3d_punch.txt"
    copy.parent.mkdir()
    copy.write_bytes((mocap.MOTIONS_DIR / "humanoid3d_punch.txt").read_bytes())
    clip = mocap.load_deepmimic(copy)
    assert (clip.name, clip.source) == ("punch", str(copy))


def test_a_moving_clip_is_not_said_to_be_still(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    text = skeleton(MIXAMO, frames=2)
    lines = text.splitlines()
    lines[-1] = " ".join(["0"] * 9 + ["20"] + ["0"] * (len(lines[-1].split()) - 10))
    path = _file(tmp_path, "moves.bvh", "\n".join(lines) + "\n")
    with caplog.at_level(logging.WARNING, logger="batteur.physics.limits"):
        load_bvh_clip(path)
    assert not [r for r in caplog.records if "no motion" in r.getMessage()]
