"""Joint rotations of any BVH motion in our body convention: joint limits from motion capture.

A BVH names its joints its own way, points its axes its own way and rests in its own pose. Three steps bring
its motion onto our 19 joints (docs/physics.md, "Joint limits"):

1. **Segments.** Each of our links (pelvis, abdomen, thorax, neck, head, and per side clavicle, upper arm,
   forearm, hand, thigh, shank, foot) is the frame of one BVH joint, found by name (:data:`SEGMENT_NAMES`: our
   own export, CMU, Mixamo, Biovision, Poser/DAZ, Blender metarig and Unreal mannequin spellings, a side given
   as a prefix or a suffix) among the descendants of the link's parent's joint; two joints for one link are an
   error, not a guess.
   BVH joints between two of them (CMU's Spine between LowerBack and Spine1) are folded into the rotation.
2. **Axes.** Up is from the hips to the head in the rest pose, right from the left shoulder (or hip) to the
   right one: ``C`` maps the file's vectors to ours (x right, y forward, z up).
3. **Rest pose.** Our zero pose stands with the arms hanging; a BVH at rest may hold a T- or A-pose. A link
   whose rest direction (to the next joint of its chain) is more than :data:`REST_TOLERANCE_RAD` from ours is
   turned onto it by the shortest arc ``A``; a smaller difference is the skeleton's own shape and is kept.

A link's orientation is ``O = C W C^T A`` (``W``: the BVH joint's world frame) and a joint's rotation is
``O_parent^T O_child``. As for DeepMimic clips (:mod:`services.physics.mocap`), the seat is not driven (the
performer's heading is not a joint's range) and the hips are taken relative to the pelvis. A spine given by
one joint for two of ours (no abdomen, or no neck) shares its rotation equally between them; an arm without a
clavicle gives the shoulder the whole rotation. Joints the file lacks keep their anatomical limits.
"""

from __future__ import annotations

import logging
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from common.character import BASE_LINK, HIP_MOUNTS, JOINT_LINKS, SIDES
from common.gesture.bvh import Bvh, BvhError, read_bvh, rest_positions, world_frames
from common.score.limbs import LimbLengths
from services.physics.mocap import MotionClip

log = logging.getLogger("batteur.physics.limits")

_SIDE_WORDS = {"left": ("left", "l"), "right": ("right", "r")}

_LIMB_NAMES: dict[str, tuple[str, ...]] = {
    # {side}: left/right, {s}: l/r; names compared lower-case without separators or a "namespace:" prefix, a side
    # suffix (Blender's upper_arm.L, Unreal's upperarm_l) turned into a prefix (:func:`_normalise`).
    # Order matters where conventions disagree: Biovision's LeftShoulder is the upper arm (beside its
    # LeftCollar), CMU's and Mixamo's the clavicle (beside their LeftArm), Blender's shoulder.L too (beside its
    # upper_arm.L); the upper arm is matched first.
    "upper_arm": ("{side}upperarm", "{side}arm", "{side}uparm", "{s}shldr", "{s}upperarm", "{side}shoulder"),
    "clavicle": ("{side}clavicle", "{side}collar", "{s}collar", "{s}clavicle", "{side}shoulder"),
    "forearm": ("{side}forearm", "{side}lowerarm", "{side}lowarm", "{s}forearm", "{side}elbow"),
    "hand": ("{side}hand", "{s}hand", "{side}wrist"),
    "thigh": ("{side}thigh", "{side}upleg", "{side}upperleg", "{s}thigh", "{side}hip"),
    "shank": ("{side}shank", "{side}leg", "{side}lowerleg", "{side}lowleg", "{side}shin", "{s}shin", "{side}calf",
              "{side}knee"),
    "foot": ("{side}foot", "{s}foot", "{side}ankle"),
}
_CENTRAL_NAMES: dict[str, tuple[str, ...]] = {
    # Blender's metarig numbers its spine bones with three digits (spine: the hips, spine.001 ... spine.003 the
    # chest, spine.004 the neck, spine.006 the head), Unreal's mannequin with two (spine_01 ... spine_03 in UE4,
    # ... spine_05 in UE5, the chest the last; neck_01): neither is mistaken for the other or for Mixamo's Spine1.
    "pelvis": ("pelvis", "hips", "hip", "root"),
    "abdomen": ("abdomen", "lowerback", "spine", "spine0", "spine001", "spine01"),
    "thorax": ("thorax", "upperchest", "chest", "spine3", "spine2", "spine1", "spine003", "spine002", "spine05",
               "spine04", "spine03", "spine02"),
    "neck": ("neck", "neck1", "neck01", "spine004"),
    "head": ("head", "spine006", "spine005"),
}

NAME_FAMILIES: tuple[tuple[str, str], ...] = (
    ("Mixamo / CMU", "Hips, Spine, Spine1, Neck, Head, LeftShoulder, LeftArm, LeftForeArm, LeftHand, LeftUpLeg, "
                     "LeftLeg, LeftFoot"),
    ("Blender metarig / Rigify", "spine, spine.001 ... spine.006, shoulder.L, upper_arm.L, forearm.L, hand.L, "
                                 "thigh.L, shin.L, foot.L (DEF- bones too)"),
    ("Unreal mannequin", "pelvis, spine_01 ... spine_05, neck_01, head, clavicle_l, upperarm_l, lowerarm_l, hand_l, "
                         "thigh_l, calf_l, foot_l"),
    ("Biovision / Poser / DAZ", "LeftCollar, LeftShoulder, LeftElbow, LeftWrist, LeftHip, LeftKnee, LeftAnkle; "
                                "lCollar, lShldr, lForeArm, lHand, lThigh, lShin, lFoot"),
    ("Batteur's own", "pelvis, abdomen, thorax, neck, head, left_clavicle, left_upper_arm, left_forearm, left_hand, "
                      "left_thigh, left_shank, left_foot"),
)
"""The joint-name conventions :data:`SEGMENT_NAMES` knows, with examples (left side; the right alike), for
messages."""


def _segment_names() -> dict[str, tuple[str, ...]]:
    names = dict(_CENTRAL_NAMES)
    for side in SIDES:
        word, letter = _SIDE_WORDS[side]
        for kind, patterns in _LIMB_NAMES.items():
            names[f"{side}_{kind}"] = tuple(p.format(side=word, s=letter) for p in patterns)
    return names


SEGMENT_NAMES: dict[str, tuple[str, ...]] = _segment_names()
"""Our link -> the BVH joint names that may stand for it (normalised: lower case, no separators), first found
wins, in :data:`MATCH_ORDER`."""

JOINT_SEGMENTS: dict[str, tuple[str, str]] = {
    joint: ("pelvis" if parent in HIP_MOUNTS.values() else parent, child)
    for joint, (parent, child) in JOINT_LINKS.items() if parent != BASE_LINK}
"""Our joint -> (parent link, child link) as read from a BVH: the body's tree (common.character) without the
seat, the thighs hanging from the pelvis (see the module docstring)."""

SEGMENT_PARENT: dict[str, str] = {child: parent for parent, child in JOINT_SEGMENTS.values()}
"""Our link -> its parent link in the chain the BVH is read along."""

MATCH_ORDER: tuple[str, ...] = ("pelvis", "abdomen", "thorax", "neck", "head") + tuple(
    f"{s}_{k}" for s in SIDES for k in ("upper_arm", "clavicle", "forearm", "hand", "thigh", "shank", "foot"))

REST_DIRECTION: dict[str, np.ndarray] = {
    "abdomen": np.array([0.0, 0.0, 1.0]), "thorax": np.array([0.0, 0.0, 1.0]), "neck": np.array([0.0, 0.0, 1.0]),
    "head": np.array([0.0, 0.0, 1.0]),
    **{f"{s}_{k}": d for s, x in (("left", -1.0), ("right", 1.0)) for k, d in (
        ("clavicle", np.array([x, 0.0, 0.0])), ("upper_arm", np.array([0.0, 0.0, -1.0])),
        ("forearm", np.array([0.0, 0.0, -1.0])), ("hand", np.array([0.0, 0.0, -1.0])),
        ("thigh", np.array([0.0, 0.0, -1.0])), ("shank", np.array([0.0, 0.0, -1.0])),
        ("foot", np.array([0.0, 1.0, 0.0])))},
}
"""Our link's direction towards the next joint of its chain in our zero pose (body axes; the foot: forward,
compared in the horizontal plane, its pitch being the skeleton's shape)."""

NEXT_SEGMENT: dict[str, str] = {
    "abdomen": "thorax", "thorax": "neck", "neck": "head",
    **{f"{s}_{a}": f"{s}_{b}" for s in SIDES for a, b in (
        ("clavicle", "upper_arm"), ("upper_arm", "forearm"), ("forearm", "hand"), ("thigh", "shank"),
        ("shank", "foot"))},
}

REST_TOLERANCE_RAD = math.radians(30.0)
"""A link's rest direction further than this from ours is a different rest pose (a T- or A-pose arm), turned
onto ours; closer, it is the skeleton's shape (a spine's curve, a toe-out) and left as it is."""

SHARED: dict[str, tuple[str, str]] = {"abdomen": ("lumbar", "thoracic"), "neck": ("neck", "head")}
"""A central link the BVH lacks -> our two joints that share the rotation across it equally."""


_SIDE_SUFFIX = re.compile(r"^(?P<base>.+?)[\s_\-.](?P<side>l|r|left|right)$", re.IGNORECASE)
"""A side given after the name (Blender's ``upper_arm.L``, Unreal's ``upperarm_l``, ``thigh-R``)."""


def _normalise(name: str) -> str:
    """A joint's name as :data:`SEGMENT_NAMES` spells it: without a ``namespace:`` prefix (Mixamo's) or a Blender
    ``DEF-`` one, a side suffix made a prefix (``upper_arm.L``: ``leftupperarm``), lower case without separators."""
    bare = name.rsplit(":", 1)[-1]
    bare = re.sub(r"^def[\-_.]", "", bare, flags=re.IGNORECASE)
    match = _SIDE_SUFFIX.match(bare)
    if match is not None:
        side = match["side"].lower()
        bare = ("left" if side in ("l", "left") else "right") + match["base"]
    return re.sub(r"[\s_\-.]", "", bare).lower()


def map_segments(bvh: Bvh, name: str = "<bvh>") -> dict[str, int]:
    """Our link -> the index of the BVH joint standing for it (only the links found; the pelvis always, the BVH
    root if no joint is named for it). A link's joint must descend from its parent link's (or the nearest
    mapped ancestor's), and no BVH joint stands for two links.

    Raises :class:`BvhError` (``name``: the file) when two joints could stand for one link by the same name
    (``upper_arm.L`` beside ``DEF-upper_arm.L``, ``LeftHand`` beside ``hand.L``): which one is meant is not
    guessed."""
    normal = [_normalise(j.name) for j in bvh.joints]
    ancestors: list[set[int]] = []
    for j in bvh.joints:
        ancestors.append(set() if j.parent < 0 else ancestors[j.parent] | {j.parent})
    found: dict[str, int] = {}
    used: set[int] = set()
    # Blender's hips bone is "spine", the parent of "spine.001": a Rigify export puts a floor bone "root" above it
    chain_hips = {j.parent for j, n in zip(bvh.joints, normal, strict=True) if n == "spine001" and j.parent >= 0
                  and normal[j.parent] == "spine"}
    for link in MATCH_ORDER:
        above = _mapped_ancestor(link, found)
        for candidate in SEGMENT_NAMES[link]:
            if link == "pelvis" and candidate == "root" and len(chain_hips) == 1:  # the chain's hips, not the floor
                hits = list(chain_hips)
            else:
                hits = [i for i, n in enumerate(normal) if n == candidate and i not in used
                        and (above is None or found[above] in ancestors[i])]
            if len(hits) > 1:
                joints = " and ".join(repr(bvh.joints[i].name) for i in hits[:3])
                raise BvhError(f"{name}: joints {joints} could each be the {link.replace('_', ' ')}: rename or "
                               "remove all but one (which one is meant is not guessed)")
            if hits:
                found[link] = hits[0]
                used.add(hits[0])
                break
        if link == "pelvis" and "pelvis" not in found:
            found["pelvis"] = 0
            used.add(0)
    return found


def unmatched_words(bvh: Bvh) -> str:
    """What a file none of whose joints is found by name is told: the names it has (the first few) and the
    conventions known (:data:`NAME_FAMILIES`)."""
    names = [j.name for j in bvh.joints]
    seen = ", ".join(names[:8]) + (f", ... ({len(names)} joints)" if len(names) > 8 else "")
    known = "; ".join(f"{family}: {examples}" for family, examples in NAME_FAMILIES)
    return f"its joints are {seen}; the names known are those of {known}"


def _mapped_ancestor(link: str, found: dict[str, int]) -> str | None:
    parent = SEGMENT_PARENT.get(link)
    while parent is not None and parent not in found:
        parent = SEGMENT_PARENT.get(parent)
    return parent


def body_axes(rest: np.ndarray, segments: dict[str, int], name: str = "<bvh>") -> np.ndarray:
    """(3, 3) ``C``: rows are our right, forward and up axes in the file's; ``C v`` is a file vector in ours.

    Raises :class:`BvhError` when the rest pose does not tell up (no head, neck or thorax above the pelvis) or
    right (no left and right shoulders or hips)."""
    top = next((segments[k] for k in ("head", "neck", "thorax") if k in segments), None)
    if top is None:
        raise BvhError(f"{name}: no head, neck or chest joint: cannot tell which way is up")
    up = rest[top] - rest[segments["pelvis"]]
    for kind in ("upper_arm", "clavicle", "thigh"):  # on the trunk first: a thigh's offset may follow the legs
        left, right = segments.get(f"left_{kind}"), segments.get(f"right_{kind}")
        if left is not None and right is not None:
            across = rest[right] - rest[left]
            break
    else:
        raise BvhError(f"{name}: no left and right shoulders or hips: cannot tell left from right")
    if np.linalg.norm(up) < 1e-9:
        raise BvhError(f"{name}: the head is at the hips in the rest pose: cannot tell which way is up")
    up = up / np.linalg.norm(up)
    across = across - np.dot(across, up) * up
    if np.linalg.norm(across) < 1e-9:
        raise BvhError(f"{name}: left and right lie along the spine in the rest pose: cannot tell them apart")
    right = across / np.linalg.norm(across)
    return np.array([right, np.cross(up, right), up])


def rest_alignment(link: str, direction: np.ndarray) -> Rotation | None:
    """``A``: turns our link's zero-pose frame onto the BVH's rest frame of it, given the link's rest
    ``direction`` in our axes (see :data:`REST_TOLERANCE_RAD`); identity within the tolerance, None when the
    direction says nothing (zero; a foot's pointing more down than forward, as an end site along the shank)."""
    ours = REST_DIRECTION[link]
    d = np.array(direction, dtype=float)
    length = float(np.linalg.norm(d))
    if link.endswith("foot"):
        d[2] = 0.0
    if length < 1e-9 or float(np.linalg.norm(d)) < 0.3 * length:
        return None
    d /= np.linalg.norm(d)
    angle = math.acos(float(np.clip(np.dot(ours, d), -1.0, 1.0)))
    if angle <= REST_TOLERANCE_RAD:
        return Rotation.identity()
    axis = np.cross(ours, d)
    if np.linalg.norm(axis) < 1e-9:  # opposite: any perpendicular axis (a limb pointing up at rest)
        axis = np.cross(ours, [1.0, 0.0, 0.0] if abs(ours[0]) < 0.9 else [0.0, 1.0, 0.0])
    return Rotation.from_rotvec(axis / np.linalg.norm(axis) * angle)


def _rest_direction(bvh: Bvh, rest: np.ndarray, link: str, segments: dict[str, int]) -> np.ndarray | None:
    """The link's rest direction in the file (to the next mapped link's joint, else its first child joint or end
    site), or None when it has nothing beyond it."""
    i = segments[link]
    nxt = NEXT_SEGMENT.get(link)
    while nxt is not None and nxt not in segments:
        nxt = NEXT_SEGMENT.get(nxt)
    if nxt is not None:
        return rest[segments[nxt]] - rest[i]
    joint = bvh.joints[i]
    if joint.children:
        return np.asarray(bvh.joints[joint.children[0]].offset, dtype=float)
    return None if joint.end_site is None else np.asarray(joint.end_site, dtype=float)


def _half(rot: Rotation) -> Rotation:
    return Rotation.from_rotvec(rot.as_rotvec() / 2.0)


def bvh_clip(bvh: Bvh, name: str = "<bvh>", where: str | None = None) -> MotionClip:
    """Our joints' rotations over the BVH's frames (see the module docstring); ``name`` names the clip,
    ``where`` (default: the name) the file in errors.

    Raises :class:`BvhError` when no joint of ours can be read (nothing matches our links' names, or the rest
    pose does not tell up and right).
    """
    where = where or name
    segments = map_segments(bvh, where)
    rest = rest_positions(bvh)
    c = body_axes(rest, segments, where)
    to_ours = Rotation.from_matrix(c)
    world, _ = world_frames(bvh)
    frames: dict[str, Rotation] = {"pelvis": to_ours * world[segments["pelvis"]] * to_ours.inv()}
    aligned: dict[str, Rotation] = {"pelvis": Rotation.identity()}
    for link in MATCH_ORDER[1:]:  # parents first
        if link not in segments:
            continue
        direction = _rest_direction(bvh, rest, link, segments)
        align = None if direction is None else rest_alignment(link, c @ direction)
        if align is None:  # nothing tells its rest direction: it continues its parent's
            align = aligned[_mapped_ancestor(link, segments) or "pelvis"]
        aligned[link] = align
        frames[link] = to_ours * world[segments[link]] * to_ours.inv() * align
    rotations: dict[str, Rotation] = {}
    for joint, (parent, child) in JOINT_SEGMENTS.items():
        if parent in frames and child in frames:
            rotations[joint] = frames[parent].inv() * frames[child]
    for missing, (lower, upper) in SHARED.items():
        below, above = SEGMENT_PARENT[missing], NEXT_SEGMENT[missing]
        if missing not in frames and below in frames and above in frames:
            rotations[lower] = rotations[upper] = _half(frames[below].inv() * frames[above])
    for side in SIDES:  # no clavicle: the shoulder turns the arm from the thorax
        arm = f"{side}_upper_arm"
        if f"{side}_clavicle" not in frames and arm in frames and "thorax" in frames:
            rotations[f"{side}_shoulder"] = frames["thorax"].inv() * frames[arm]
    if not rotations:
        raise BvhError(f"{where}: none of its joints could be matched to the body's (hips, spine, neck, head, arms, "
                       f"legs by their usual BVH names): {unmatched_words(bvh)}")
    times = np.arange(len(bvh.motion)) * bvh.frame_time
    return MotionClip(name, times, rotations, where)


def load_bvh_clip(path: str | Path) -> MotionClip:
    """:func:`bvh_clip` of a BVH file, named by its stem; :class:`BvhError` (a ``ValueError``) naming the file
    for one that cannot be read or has fewer than two frames. A clip whose frames all hold one pose (a T-pose
    exported on its own) is logged once: it tells no range of motion."""
    p = Path(path)
    bvh = read_bvh(p)
    if len(bvh.motion) < 2:
        raise BvhError(f"{p}: {len(bvh.motion)} motion frame(s): a range of motion needs at least two")
    clip = bvh_clip(bvh, p.stem, str(p))
    if bool(np.all(bvh.motion == bvh.motion[0])):
        log.warning("clip %s has no motion (its %d frames hold one pose): it tells no range, so its joints keep "
                    "their anatomical limits (beside other clips it only adds that pose)", p, len(bvh.motion))
    return clip


LENGTH_SEGMENTS: tuple[str, ...] = ("upper_arm", "forearm", "thigh", "shank")
"""The limb segments whose length a skeleton tells without doubt: from one joint centre to the next (a hand's or
a foot's end is placed differently from one convention to another, so they keep the table's)."""

METRES_PER_SKELETON_UNIT: dict[str, float] = {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254}
"""A skeleton file's length unit -> metres per unit (a BVH does not say its unit)."""
STATURE_RANGE_M = (1.2, 2.2)
"""The performers' heights, metres (anthropometry's bounds, the physics node's and render's ``HEIGHT_RANGE_M``): a
skeleton's unit is one in which its stature is within them."""
UNIT_WORDS: dict[str, str] = {"m": "metres", "cm": "centimetres", "mm": "millimetres", "in": "inches"}
CENTIMETRES_ABOVE = 3.0
"""The first guess of a skeleton's unit: centimetres when an offset is longer than this, else metres (no joint
of a performer is 3 m from its parent)."""


@dataclass(frozen=True)
class SkeletonReading:
    """A BVH skeleton's lengths (:func:`bvh_segment_lengths`) and the unit they were read in."""

    lengths_m: dict[str, float]
    """Lengths, metres (what the file lacks is left out)."""
    unit: str
    """Key of :data:`METRES_PER_SKELETON_UNIT`."""
    why: str
    """Why that unit, for messages ("its longest offset, 100, is over 3", "given")."""
    fits: bool = True
    """False when no unit gives a performer (:func:`read_skeleton`): the lengths are the first guess's."""
    given: bool = False
    """True when the unit was given (``--skeleton-units``), not guessed."""
    joints: dict[str, str] = field(default_factory=dict)
    """Length name -> the file's joints it was measured between ("LeftShoulder to RightShoulder"), for messages."""

    @property
    def unit_words(self) -> str:
        return f"{UNIT_WORDS[self.unit]}: {self.why}"

    @property
    def stature_m(self) -> float | None:
        """The height of a performer of de Leva's proportions with these lengths (:func:`skeleton_stature`)."""
        return skeleton_stature(self.lengths_m)

    @property
    def joints_words(self) -> str:
        """Which joints each length was measured between and which lengths no joint was found for (by name:
        :data:`SEGMENT_NAMES`), a sentence ending an error about the lengths: a joint named otherwise than expected
        is taken for another segment (a Mixamo skeleton without LeftArm: its LeftShoulder, the clavicle, read as the
        upper arm, as Biovision's LeftShoulder is) or not found."""
        said = "; ".join(f"{_length_words(name)} {joints}" for name, joints in self.joints.items())
        missing = [_length_words(name) for name in MEASURED if name not in self.joints
                   and not (name == "shoulder_height" and "trunk" in self.joints)]
        lacking = f"; no joints found for the {', '.join(missing)}" if missing else ""
        return (f"The lengths were measured between these joints, found by name (a joint named otherwise is taken "
                f"for another segment or not found): {said}{lacking}")


MEASURED: tuple[str, ...] = (*LENGTH_SEGMENTS, "neck", "shoulder_height", "shoulder_width", "hip_width")
"""The lengths a skeleton may give (:func:`bvh_segment_lengths`; ``trunk`` in place of ``shoulder_height`` without
shoulders)."""


def _length_words(name: str) -> str:
    """A length's name for messages: ``shoulder_width`` -> ``shoulder width``."""
    return name.replace("_", " ")


def _raw_lengths(bvh: Bvh, segments: dict[str, int], where: str) -> dict[str, float]:
    """:func:`bvh_segment_lengths`' lengths in the file's own units."""
    return _measured(bvh, segments, where)[0]


def _measured(bvh: Bvh, segments: dict[str, int], where: str) -> tuple[dict[str, float], dict[str, str]]:
    """:func:`bvh_segment_lengths`' lengths in the file's own units, and the joints each was measured between
    (:attr:`SkeletonReading.joints`)."""
    rest = rest_positions(bvh)

    def joint_name(link: str) -> str:
        return bvh.joints[segments[link]].name

    def between(*pairs: tuple[str, str]) -> str | None:  # "LeftArm to LeftForeArm and RightArm to RightForeArm"
        known = [f"{joint_name(a)} to {joint_name(b)}" for a, b in pairs if a in segments and b in segments]
        return " and ".join(known) or None

    joints: dict[str, str | None] = {
        kind: between(*((f"{s}_{kind}", NEXT_SEGMENT[f"{s}_{kind}"]) for s in SIDES)) for kind in LENGTH_SEGMENTS}
    joints["neck"] = between(("neck", "head"))
    if all(f"{s}_thigh" in segments for s in SIDES):
        hip_joints = " and ".join(joint_name(f"{s}_thigh") for s in SIDES)
        joints["hip_width"] = between(("left_thigh", "right_thigh"))
        if all(f"{s}_upper_arm" in segments for s in SIDES):
            joints["shoulder_height"] = (f"the hips ({hip_joints}) up to the shoulders ("
                                         f"{' and '.join(joint_name(f'{s}_upper_arm') for s in SIDES)})")
        elif "neck" in segments:
            joints["trunk"] = f"the hips ({hip_joints}) up to {joint_name('neck')}"
    joints["shoulder_width"] = between(("left_upper_arm", "right_upper_arm"))

    def at(link: str) -> np.ndarray | None:  # the centre of the joint that starts ``link``
        return rest[segments[link]] if link in segments else None

    def distance(a: np.ndarray | None, b: np.ndarray | None) -> float | None:
        return None if a is None or b is None else float(np.linalg.norm(b - a))

    lengths: dict[str, float | None] = {}
    for kind in LENGTH_SEGMENTS:
        sides = [distance(at(f"{s}_{kind}"), at(NEXT_SEGMENT[f"{s}_{kind}"])) for s in SIDES]
        known = [d for d in sides if d is not None]
        lengths[kind] = float(np.mean(known)) if known else None
    lengths["neck"] = distance(at("neck"), at("head"))
    hips, shoulders, neck = [at(f"{s}_thigh") for s in SIDES], [at(f"{s}_upper_arm") for s in SIDES], at("neck")
    if hips[0] is not None and hips[1] is not None:
        lengths["hip_width"] = distance(hips[0], hips[1])
        hip_centre = (hips[0] + hips[1]) / 2
        try:  # heights above the hips: the hip joints may sit forward of the spine
            up = body_axes(rest, segments, where)[2]
        except BvhError:  # no pelvis to tell up from
            up = None
        if shoulders[0] is not None and shoulders[1] is not None:  # what places the arms: the trunk follows it
            top, name = (shoulders[0] + shoulders[1]) / 2, "shoulder_height"
        else:
            top, name = neck, "trunk"
        if top is not None:
            lengths[name] = distance(hip_centre, top) if up is None else float(np.dot(top - hip_centre, up))
    lengths["shoulder_width"] = distance(*(at(f"{s}_upper_arm") for s in SIDES))
    measured = {name: length for name, length in lengths.items() if length is not None}
    return measured, {name: words for name, words in joints.items() if words is not None and name in measured}


def _problem(lengths_m: dict[str, float], joints: dict[str, str] | None = None) -> str | None:
    """Why no body can have these lengths (:func:`anthropometry`'s ``ValueError``), None when one can; a length
    measured between ``joints`` (:attr:`SkeletonReading.joints`) is said to be."""
    from services.physics.anthropometry import LengthError, anthropometry

    try:
        anthropometry(lengths_m=lengths_m)
    except LengthError as exc:
        where = (joints or {}).get(exc.segment)
        return str(exc) if where is None else f"{exc}, measured from {where}"
    except ValueError as exc:
        return str(exc)
    return None


def _scaled(raw: dict[str, float], unit: str) -> dict[str, float]:
    return {name: length * METRES_PER_SKELETON_UNIT[unit] for name, length in raw.items()}


def read_skeleton(path: str | Path, units: str = "auto") -> SkeletonReading:
    """A BVH skeleton's lengths in metres (see :func:`bvh_segment_lengths`) and the unit they were read in.

    ``units``: a key of :data:`METRES_PER_SKELETON_UNIT`, or ``auto``: the unit in which a performer has the lengths
    and the stature they imply (:func:`skeleton_stature`) is within :data:`STATURE_RANGE_M` (the units are too far
    apart for two to fit; several would be told apart by the stature nearest de Leva's 1.75 m). The first guess,
    centimetres when an offset is longer than :data:`CENTIMETRES_ABOVE`, else metres, is kept when it fits or when
    no unit does (:attr:`SkeletonReading.fits` False, :attr:`SkeletonReading.why` giving each unit's stature);
    another unit is said in :attr:`SkeletonReading.why`. Raises what reading the file raises."""
    if units != "auto" and units not in METRES_PER_SKELETON_UNIT:
        raise ValueError(f"skeleton units {units!r}: auto, {', '.join(METRES_PER_SKELETON_UNIT)} expected")
    bvh = read_bvh(path)
    raw, joints = _measured(bvh, map_segments(bvh, str(path)), str(path))
    if units != "auto":
        return SkeletonReading(_scaled(raw, units), units, "as given", given=True, joints=joints)
    longest = max((float(np.linalg.norm(j.offset)) for j in bvh.joints), default=0.0)
    first = "cm" if longest > CENTIMETRES_ABOVE else "m"
    why = f"its longest offset, {longest:.4g}, is {'over' if first == 'cm' else 'at most'} {CENTIMETRES_ABOVE:g}"
    if not raw:  # no limb found: nothing to tell a unit by (the caller says so)
        return SkeletonReading({}, first, why, joints=joints)
    problems = {u: _unit_problem(raw, u, joints) for u in METRES_PER_SKELETON_UNIT}
    fits = [u for u, problem in problems.items() if problem is None]
    if first in fits:
        return SkeletonReading(_scaled(raw, first), first, why, joints=joints)
    if not fits:  # the first guess's problem is the caller's to say (usable_segment_lengths): here the others'
        low, high = STATURE_RANGE_M
        others = ", ".join(f"in {UNIT_WORDS[u]} {_unit_words(raw, u, joints)}" for u in METRES_PER_SKELETON_UNIT
                           if u != first)
        return SkeletonReading(_scaled(raw, first), first, f"{why}; no other unit gives a performer's lengths "
                               f"either: {others} (a performer is {low:g} to {high:g} m tall)", fits=False,
                               joints=joints)
    unit = min(fits, key=lambda u: abs(math.log((skeleton_stature(_scaled(raw, u)) or 1.75) / 1.75)))
    return SkeletonReading(_scaled(raw, unit), unit, f"no performer has its lengths in {UNIT_WORDS[first]}, the "
                           f"first guess ({why}): {problems[first]}", joints=joints)


def _unit_words(raw: dict[str, float], unit: str, joints: dict[str, str]) -> str:
    """Why no performer has the lengths ``raw`` read in ``unit``, for a list of units: the stature they make when it
    is outside :data:`STATURE_RANGE_M` (a unit mistaken), else the length no body has, with the stature (the
    joints mistaken: a stature within the range beside "no unit fits" read as a contradiction)."""
    lengths = _scaled(raw, unit)
    stature, (low, high) = skeleton_stature(lengths), STATURE_RANGE_M
    if stature is None:
        return _problem(lengths, joints) or "no performer's lengths"
    if not low <= stature <= high:
        return f"a {stature:g} m performer's"
    problem = _problem(lengths, joints)
    return f"a {stature:g} m performer's, but {problem}" if problem else f"a {stature:g} m performer's"


def _unit_problem(raw: dict[str, float], unit: str, joints: dict[str, str] | None = None) -> str | None:
    """Why no performer has the lengths ``raw`` read in ``unit`` (:func:`_performer_problem`); None when one has."""
    return _performer_problem(_scaled(raw, unit), joints)


def _performer_problem(lengths_m: dict[str, float], joints: dict[str, str] | None = None) -> str | None:
    """Why no performer has these lengths: a length no body has (:func:`_problem`, said with the ``joints`` it was
    measured between) or a stature (:func:`skeleton_stature`) outside :data:`STATURE_RANGE_M`; None when one has."""
    problem = _problem(lengths_m, joints)
    if problem is not None:
        return problem
    stature, (low, high) = skeleton_stature(lengths_m), STATURE_RANGE_M
    if stature is not None and not low <= stature <= high:
        return f"its lengths are a {stature:g} m performer's, not {low:g} to {high:g} m tall"
    return None


def skeleton_stature(lengths_m: dict[str, float]) -> float | None:
    """The height (metres, 3 significant digits) of a performer of de Leva's proportions whose arms, legs, neck,
    trunk and widths (:func:`bvh_segment_lengths`' names) add up to the same as ``lengths_m``'s; None without any of
    them. An estimate for a skeleton's hands, feet and head, which it does not give."""
    from services.physics.anthropometry import SHOULDER_BELOW_NECK, TRUNK_SEGMENTS, anthropometry

    table = anthropometry(1.75)
    trunk = sum(table.segments[name].length_m for name in TRUNK_SEGMENTS)
    reference = {**{name: table.segments[name].length_m for name in (*LENGTH_SEGMENTS, "neck")},
                 "trunk": trunk, "shoulder_height": trunk - SHOULDER_BELOW_NECK * table.scale,
                 "shoulder_width": table.shoulder_width_m, "hip_width": table.hip_width_m}
    given = [name for name in reference if name in lengths_m]
    if not given:
        return None
    ratio = sum(lengths_m[name] for name in given) / sum(reference[name] for name in given)
    return float(f"{1.75 * ratio:.3g}")


def bvh_segment_lengths(path: str | Path, units_to_m: float | None = None, units: str = "auto") -> dict[str, float]:
    """Lengths (metres) from a BVH skeleton's rest pose, for :func:`anthropometry`'s ``lengths_m``, each measured
    between joint centres found by :func:`map_segments` (what the file lacks is left out):

    - :data:`LENGTH_SEGMENTS`, the mean of both sides where both are;
    - ``neck``: the neck joint to the head joint;
    - ``shoulder_height``: the shoulder joints' height above the hip joints (midpoints; what places the arms at
      the kit), or where the file has no shoulders, ``trunk``: the neck joint's;
    - ``shoulder_width`` and ``hip_width``: between the two shoulder joints, the two hip joints.

    ``units_to_m``: factor from the file's units to metres; by default the unit ``units`` (:func:`read_skeleton`'s:
    ``auto`` guesses it).
    """
    if units_to_m is None:
        return read_skeleton(path, units).lengths_m
    bvh = read_bvh(path)
    return {name: length * units_to_m for name, length in _raw_lengths(bvh, map_segments(bvh, str(path)),
                                                                         str(path)).items()}


def usable_segment_lengths(path: str | Path, units: str = "auto") -> dict[str, float]:
    """:func:`bvh_segment_lengths` of a skeleton a body can be built from (``--skeleton-bvh`` of ``batteur render``
    and of the physics node, checked at their start), read in ``units`` (:func:`read_skeleton`'s). :class:`BvhError`
    naming the file when none of its joints is found by name (without it the body would silently be de Leva's; the
    names it has and those known are said) or for proportions no body has (the unit it was read in is said, and
    when guessed, the stature each unit implies); with the unit guessed, a stature no performer has is refused too
    (the guess found none), with a unit given it is the user's to choose (:func:`stature_warning` says it); what
    reading the file raises."""
    reading = read_skeleton(path, units)
    if not reading.lengths_m:
        raise BvhError(f"{path}: no arm, leg or trunk joints found by their usual BVH names: "
                       f"{unmatched_words(read_bvh(path))}")
    if units == "auto":
        problem = _performer_problem(reading.lengths_m, reading.joints)
    else:  # a child-sized or stylised character the user says the unit of: built if a body can have its lengths
        problem = _problem(reading.lengths_m, reading.joints)
        stature = reading.stature_m
        if problem is not None and stature is not None:  # which performer the unit given makes: a unit mistaken
            problem += f"; its lengths are a {stature:g} m performer's"
    if problem is not None:  # a skeleton lying down, a child's, in a unit no guess finds, joints mistaken
        raise BvhError(f"{path}: {problem}, read in {reading.unit_words}. {reading.joints_words}")
    return reading.lengths_m


def stature_warning(reading: SkeletonReading) -> str | None:
    """What a skeleton read in a unit given (not guessed: a guess keeps to performers) means for the drummer when
    its lengths are those of a performer outside :data:`STATURE_RANGE_M` (:attr:`SkeletonReading.stature_m`); None
    within it. For the start of ``batteur render`` and of the physics node, which build it anyway."""
    stature, (low, high) = reading.stature_m, STATURE_RANGE_M
    if not reading.given or stature is None or low <= stature <= high:
        return None
    if stature < low:
        means = ("its shorter arms and legs may not reach every instrument of a kit set for a performer (the notes "
                 "there are missed; the kit's reach warning names the instruments)")
    else:
        means = "its longer arms and legs play a kit set for a shorter performer, cramped"
    return (f"the skeleton, read in {UNIT_WORDS[reading.unit]} as given, has a {stature:g} m performer's lengths, "
            f"outside the {low:g} to {high:g} m of the performers the kits are set for: the drummer gets its arms, "
            f"legs, neck and trunk (the hands, feet and head and the place over the throne follow the drummer's "
            f"height); {means}")


def skeleton_limb_lengths(path: str | Path, height_m: float, mass_kg: float, units: str = "auto") -> LimbLengths:
    """The arms (upper arm + forearm + hand) and legs (thigh + shank) of the body physics builds from the skeleton
    of the BVH file at ``path``, read in ``units`` (:func:`read_skeleton`'s), metres: the segments the file lacks
    are de Leva's for ``height_m`` (as ``anthropometry(lengths_m=...)`` takes them). For the planner's reach
    (``batteur render --skeleton-bvh``, the physics node's). Raises what reading the file raises (``OSError``,
    ``ValueError``)."""
    from services.physics.anthropometry import anthropometry

    segments = anthropometry(height_m, mass_kg, lengths_m=bvh_segment_lengths(path, units=units)).segments
    return LimbLengths.of_segments({name: s.length_m for name, s in segments.items()})
