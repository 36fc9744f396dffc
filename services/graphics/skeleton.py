"""Which link hangs from which: a parent for every link name physics publishes.

``/batteur/skeleton`` carries link names only. The view draws bones between a
link and its parent, and the BVH export needs a tree, so the tree is inferred
from the names: a side (``left_``/``right_``, ``l_``/``r_``, ``_l``/``_r``)
and a body part with common aliases (``upper_arm`` = ``shoulder``, ``shin`` =
``knee`` = ``lower_leg``, ...). A link whose canonical parent is missing hangs
from the nearest present ancestor; a name that is no body part has no parent
(-1) and is drawn as a marker; kit links (``kit.<object id>[.<part>]``, see
:func:`kit_link`) animate the kit instead.
"""

from __future__ import annotations

import re

ALIASES: dict[str, str] = {
    "pelvis": "pelvis", "root": "pelvis", "hips": "pelvis", "hip_center": "pelvis", "base": "pelvis",
    "abdomen": "abdomen", "spine": "abdomen", "lower_back": "abdomen", "waist": "abdomen", "torso": "abdomen",
    "chest": "chest", "thorax": "chest", "upper_back": "chest", "spine2": "chest",
    "neck": "neck",
    "head": "head", "skull": "head",
    "clavicle": "clavicle", "collar": "clavicle",
    "upper_arm": "upper_arm", "shoulder": "upper_arm", "humerus": "upper_arm", "arm": "upper_arm",
    "forearm": "forearm", "elbow": "forearm", "lower_arm": "forearm",
    "hand": "hand", "wrist": "hand", "palm": "hand",
    "stick": "stick", "drumstick": "stick",
    "stick_tip": "stick_tip", "tip": "stick_tip", "drumstick_tip": "stick_tip",
    "thigh": "thigh", "hip": "thigh", "upper_leg": "thigh", "femur": "thigh",
    "shin": "shin", "shank": "shin", "knee": "shin", "lower_leg": "shin", "calf": "shin", "leg": "shin",
    "foot": "foot", "ankle": "foot",
    "toe": "toe", "toes": "toe", "ball": "toe", "ball_of_foot": "toe", "foot_ball": "toe",
}

CANONICAL_PARENT: dict[str, str | None] = {
    "pelvis": None,
    "abdomen": "pelvis",
    "chest": "abdomen",
    "neck": "chest",
    "head": "neck",
    "clavicle": "chest",
    "upper_arm": "clavicle",
    "forearm": "upper_arm",
    "hand": "forearm",
    "stick": "hand",
    "stick_tip": "stick",
    "thigh": "pelvis",
    "shin": "thigh",
    "foot": "shin",
    "toe": "foot",
}

SIDED = {"clavicle", "upper_arm", "forearm", "hand", "stick", "stick_tip", "thigh", "shin", "foot", "toe"}

_SIDE_PATTERNS = (
    (re.compile(r"^(left|l)[_.-](.+)$"), "left"),
    (re.compile(r"^(right|r)[_.-](.+)$"), "right"),
    (re.compile(r"^(.+)[_.-](left|l)$"), "left"),
    (re.compile(r"^(.+)[_.-](right|r)$"), "right"),
)


def canonical(name: str) -> tuple[str, str] | None:
    """``(side, part)`` for a body link name (side '' for the trunk), None for anything else."""
    low = name.lower()
    side = ""
    part = low
    for pattern, which in _SIDE_PATTERNS:
        m = pattern.match(low)
        if m:
            side = which
            part = m.group(2) if which and m.group(1) in ("left", "l", "right", "r") else m.group(1)
            break
    part = part.replace("-", "_").replace(".", "_")
    if part in ALIASES:
        part = ALIASES[part]
    elif part.endswith("_tip") and "stick" in part:
        part = "stick_tip"
    else:
        return None
    if (part in SIDED) != bool(side):
        return None
    return side, part


def guess_parents(names: list[str]) -> list[int]:
    """Index of each link's parent in ``names`` (-1: no parent). Never raises.

    >>> guess_parents(["pelvis", "right_thigh", "right_shin", "crash"])
    [-1, 0, 1, -1]
    """
    keys: dict[tuple[str, str], int] = {}
    for i, name in enumerate(names):
        key = canonical(name)
        if key is not None and key not in keys:
            keys[key] = i
    parents: list[int] = []
    for i, name in enumerate(names):
        key = canonical(name)
        if key is None or keys.get(key) != i:
            parents.append(-1)
            continue
        side, part = key
        parent = CANONICAL_PARENT[part]
        found = -1
        while parent is not None:
            p_side = side if parent in SIDED else ""
            if (p_side, parent) in keys:
                found = keys[(p_side, parent)]
                break
            parent = CANONICAL_PARENT[parent]
        parents.append(found)
    return parents


def kit_link(name: str) -> tuple[str, str] | None:
    """``(object id, part)`` of a kit link published by physics (``kit.ride`` -> ``("ride", "")``,
    ``kit.hihat.top`` -> ``("hihat", "top")``, ``kit.kick_pedal.footboard``); None for other names."""
    if not name.startswith("kit."):
        return None
    rest = name[4:]
    obj, _, part = rest.partition(".")
    return (obj, part) if obj else None


def body_links(names: list[str]) -> list[int]:
    """Indices of links that belong to the body tree (a recognised body part)."""
    return [i for i, n in enumerate(names) if canonical(n) is not None]
