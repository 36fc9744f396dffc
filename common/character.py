"""The percussionist's joint layout, shared by physics (which builds the body) and graphics (the pose editor).

19 joints x 3 revolute DOF = 57 DOF (Bouënard et al. 2009). A DOF is named
``<joint>_x`` / ``_y`` / ``_z``; a joint's child link frame is the parent's
link frame turned by ``Rx(q_x) Ry(q_y) Rz(q_z)`` (intrinsic x-y-z Euler
angles, radians) about the joint origin, which is the child link's frame origin
(the frames /batteur/pose carries). Body frame: x to the performer's right, y
forward, z up; in the zero pose every link frame is aligned with the world.

Only names and the tree are here; sizes, masses and limits are physics'
(services/physics/character.py builds the URDF from this layout).
"""

from __future__ import annotations

SIDES = ("left", "right")
CENTRAL_JOINTS = ("seat", "lumbar", "thoracic", "neck", "head")
LIMB_JOINTS = ("clavicle", "shoulder", "elbow", "wrist", "hip", "knee", "ankle")
JOINTS: tuple[str, ...] = CENTRAL_JOINTS + tuple(f"{s}_{j}" for s in SIDES for j in LIMB_JOINTS)
"""The 19 three-DOF joints, in DOF order."""
AXES = ("x", "y", "z")
DOF_NAMES: tuple[str, ...] = tuple(f"{j}_{a}" for j in JOINTS for a in AXES)
"""The 57 actuated DOF, in order (the order of /batteur/physics/joints and /batteur/physics/posture values)."""
N_DOF = len(DOF_NAMES)

BASE_LINK = "seat"
"""The trunk's base link (pinned to the throne, not published in /batteur/pose): the seat joint's parent."""
HIP_MOUNTS: dict[str, str] = {s: f"{s}_hip_mount" for s in SIDES}
"""Each leg's base link: fixed on the throne where the hip joint centre is at rest (the thighs rest on the seat, so
the pelvis rocking on it does not swing the legs; physics builds each leg as its own multibody)."""
BASE_LINKS: frozenset[str] = frozenset({BASE_LINK, *HIP_MOUNTS.values()})
"""Links fixed to the throne, not published in /batteur/pose."""


def _joint_links() -> dict[str, tuple[str, str]]:
    links = {"seat": (BASE_LINK, "pelvis"), "lumbar": ("pelvis", "abdomen"), "thoracic": ("abdomen", "thorax"),
             "neck": ("thorax", "neck"), "head": ("neck", "head")}
    for s in SIDES:
        links |= {f"{s}_clavicle": ("thorax", f"{s}_clavicle"), f"{s}_shoulder": (f"{s}_clavicle", f"{s}_upper_arm"),
                  f"{s}_elbow": (f"{s}_upper_arm", f"{s}_forearm"), f"{s}_wrist": (f"{s}_forearm", f"{s}_hand"),
                  f"{s}_hip": (HIP_MOUNTS[s], f"{s}_thigh"), f"{s}_knee": (f"{s}_thigh", f"{s}_shank"),
                  f"{s}_ankle": (f"{s}_shank", f"{s}_foot")}
    return links


JOINT_LINKS: dict[str, tuple[str, str]] = _joint_links()
"""joint -> (parent link, child link), in DOF order (a parent always comes before its children)."""

HELD_LINKS: dict[str, str] = {f"{s}_stick": f"{s}_hand" for s in SIDES}
"""Links moved by no actuated DOF -> the link that carries them (a stick in its hand, on a passive fulcrum)."""


def joint_kind(joint: str) -> str:
    """'left_elbow' -> 'elbow'."""
    for side in SIDES:
        if joint.startswith(side + "_"):
            return joint[len(side) + 1:]
    return joint
