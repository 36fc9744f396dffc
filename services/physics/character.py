"""The percussionist's body, generated as URDF: 19 joints x 3 revolute DOF = 57 actuated DOF.

Joints (each three revolute DOF about x, then y, then z, with two light dummy
links in between, because PyBullet's Jacobian and IK do not handle spherical
joints): ``seat`` (the pelvis rocking on the throne), ``lumbar``,
``thoracic``, ``neck``, ``head``, and left/right ``clavicle``, ``shoulder``,
``elbow``, ``wrist``, ``hip``, ``knee``, ``ankle``. A DOF is named
``<joint>_x`` / ``_y`` / ``_z``; the child's frame is
``Rx(q_x) Ry(q_y) Rz(q_z)`` (intrinsic x-y-z Euler angles) relative to the
parent. Body frame: x to the performer's right, y forward, z up. In the zero
pose the performer stands, arms hanging, palms facing the thighs, and every
link frame is aligned with the world; x is flexion/extension (sagittal), y
abduction/adduction (frontal), z the long-axis rotation.

Each hand holds a stick on a passive two-axis fulcrum (spring-damper: the
fingers), so the stick rebounds from a head. Marker links with no mass to
speak of carry the effectors: ``<side>_stick_tip`` and ``<side>_foot_ball``.

Three multibodies (:class:`BodyPart`): the trunk, whose base link ``seat`` (the
point between the ischial tuberosities) sits on the throne and carries the
pelvis, spine, head, arms and sticks; and each leg, whose base link
``<side>_hip_mount`` sits on the throne where the hip joint centre is at rest.
The thighs rest on the seat: the pelvis rocking on it (the ``seat`` DOF) does
not swing the legs, and a foot's contact with its pedal is solved through the
leg's 9 links, not through the whole body's 67 (docs/physics.md, "On the
throne").
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from common.character import AXES, DOF_NAMES, SIDES, joint_kind
from common.character import CENTRAL_JOINTS as CENTRAL_JOINTS
from common.character import JOINTS as JOINTS
from common.character import LIMB_JOINTS as LIMB_JOINTS
from services.physics.anthropometry import CLAVICLE_MIDLINE_OFFSET, SHOULDER_BELOW_NECK, Anthropometry, Segment
from services.physics.sticks import StickSpec
from services.physics.urdf import Inertial, Joint, Link, Robot, Shape

SHOULDER_ABOVE_STERNOCLAVICULAR = 0.02
"""The shoulder joint centre's height above the sternoclavicular joint / de Leva's scale (metres at the
reference stature)."""

# The joint layout (SIDES, CENTRAL_JOINTS, LIMB_JOINTS, JOINTS, AXES, DOF_NAMES, joint_kind) lives in
# common/character.py, shared with graphics' pose editor; imported here for the modules that use it from physics.

JOINT_GROUP = {
    "seat": "trunk", "lumbar": "trunk", "thoracic": "trunk", "neck": "head", "head": "head",
    "clavicle": "arms", "shoulder": "arms", "elbow": "arms", "wrist": "arms",
    "hip": "legs", "knee": "legs", "ankle": "legs",
}

TORQUE_LIMIT_NM = {
    "seat": 400.0, "lumbar": 300.0, "thoracic": 250.0, "neck": 60.0, "head": 30.0,
    "clavicle": 100.0, "shoulder": 120.0, "elbow": 80.0, "wrist": 25.0,
    "hip": 250.0, "knee": 200.0, "ankle": 100.0,
}
"""Peak joint torques for a 73 kg performer, N m (scaled with body mass)."""

DUMMY_MASS_KG = 1e-3
ARMATURE_KGM2 = {
    "seat": 0.05, "lumbar": 0.05, "thoracic": 0.04, "neck": 0.006, "head": 0.004,
    "clavicle": 0.012, "shoulder": 0.012, "elbow": 0.004, "wrist": 0.0008,
    "hip": 0.03, "knee": 0.012, "ankle": 0.003,
}
"""Rotational inertia of each joint's two dummy links, kg m^2 (73 kg, 1.75 m; scaled by mass x height^2).

It plays the part of the reflected inertia of the muscles driving the joint (a robot's rotor armature):
without it the dummy links are massless and two co-linear DOF around a light link (shoulder and
clavicle about x, neck and head) form a very fast mode that no explicit PD at 1 ms can hold. It is a few
percent of the inertia each joint moves.
"""
FULCRUM_ARMATURE_KGM2 = 3e-4
"""Inertia of the dummy link between a stick's two fulcrum axes (the fingers around the stick), kg m^2."""
STICK_GRIP_TILT_RAD = math.radians(45.0)
"""The stick leaves the fist between thumb and index, tilted this much from square to the hand toward the
fingers (about in line with the forearm when the wrist is a little flexed). Square to the hand (0) left the
wrists at their flexion limit at rest, and loud strokes whipped the stick into a second, harder touch."""
SEAT_MASS_KG = 20.0
"""Mass of the trunk's base link: the throne's cushion under the pelvis (not part of the body); each leg's base
(the cushion under a thigh) has half of it. Only a floating base pinned to the throne (``--floating-base``) moves:
heavy, so that a joint's reaction torque does not spin a light base against the pin constraint (a massless one
would be static in PyBullet, where the stable PD silently fails)."""
_SKIN = (0.86, 0.72, 0.6, 1.0)
_SHIRT = (0.2, 0.3, 0.5, 1.0)
_TROUSERS = (0.15, 0.15, 0.2, 1.0)


@dataclass(frozen=True)
class CharacterSpec:
    """Everything needed to generate the body: segments, sticks, joint limits (radians per DOF)."""

    body: Anthropometry
    stick: StickSpec = field(default_factory=StickSpec)
    limits: dict[str, tuple[float, float]] = field(default_factory=dict)
    """DOF name -> (lower, upper) radians; DOFs not listed are unlimited (+-pi)."""


@dataclass(frozen=True)
class BodyPart:
    """One multibody of the character: its robot and where its base link sits relative to the seat point
    (metres, body frame)."""

    robot: Robot
    base_offset_m: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass
class CharacterModel:
    """The generated robots and their bookkeeping (names of the effector and pose links)."""

    parts: list[BodyPart]
    """The trunk first (base ``seat``), then the left and right legs (bases ``<side>_hip_mount``)."""
    spec: CharacterSpec
    dof_names: tuple[str, ...] = DOF_NAMES
    passive: tuple[str, ...] = ()
    effectors: dict[str, str] = field(default_factory=dict)
    """limb name (left_hand, right_hand, left_foot, right_foot) -> link the controllers place."""
    tips: dict[str, str] = field(default_factory=dict)
    """limb name -> link that touches (the actual stick tip, after the fulcrum; the ball of the foot)."""
    segments: list[str] = field(default_factory=list)
    """Links that are body segments or sticks (published as poses), in order."""
    torque_limits: dict[str, float] = field(default_factory=dict)
    """DOF name -> peak torque, N m."""


def _capsule_radius(seg: Segment, density: float = 1000.0) -> float:
    length = max(seg.length_m, 1e-3)
    return max(0.02, min(0.12, math.sqrt(seg.mass_kg / (density * math.pi * length))))


def _inertial(seg: Segment, com: tuple[float, float, float], long_axis: str = "z") -> Inertial:
    ix, iy, iz = seg.inertia()
    if long_axis == "y":  # the foot: long axis forward
        ix, iy, iz = ix, iz, iy
    elif long_axis == "x":  # the clavicle: long axis lateral
        ix, iy, iz = iz, iy, ix
    return Inertial(seg.mass_kg, com=com, inertia=(ix, iy, iz, 0.0, 0.0, 0.0))


def _add_3dof(robot: Robot, model: CharacterModel, joint: str, parent: str, child: str,
              xyz: tuple[float, float, float]) -> None:
    """Three revolute DOF (x, y, z) from ``parent`` to ``child`` with dummy links between them."""
    spec = model.spec
    kind = joint_kind(joint)
    torque = TORQUE_LIMIT_NM[kind] * spec.body.mass_kg / 73.0
    links = [parent, f"{joint}_dx", f"{joint}_dy", child]
    arm = ARMATURE_KGM2[kind] * (spec.body.mass_kg / 73.0) * (spec.body.height_m / 1.75) ** 2
    for dummy in links[1:3]:
        robot.add_link(Link(dummy, Inertial(DUMMY_MASS_KG, inertia=(arm, arm, arm, 0.0, 0.0, 0.0))))
    for i, axis in enumerate(AXES):
        name = f"{joint}_{axis}"
        lo, hi = spec.limits.get(name, (-math.pi, math.pi))
        vec = (1.0 if axis == "x" else 0.0, 1.0 if axis == "y" else 0.0, 1.0 if axis == "z" else 0.0)
        robot.add_joint(Joint(name, "revolute", links[i], links[i + 1], xyz=xyz if i == 0 else (0.0, 0.0, 0.0),
                              axis=vec, lower=lo, upper=hi, effort=torque, velocity=40.0))
        model.torque_limits[name] = torque


def build_character(spec: CharacterSpec) -> CharacterModel:
    """Generate the 57-DOF percussionist (see the module docstring) as a :class:`Robot`."""
    a = spec.body
    seg = a.segments
    s = a.scale
    robot = Robot("percussionist")
    model = CharacterModel(parts=[BodyPart(robot)], spec=spec)

    def segment_link(name: str, segment: Segment, com: tuple[float, float, float], shapes: tuple[Shape, ...],
                     long_axis: str = "z", robot: Robot = robot) -> None:
        robot.add_link(Link(name, _inertial(segment, com, long_axis), shapes))
        model.segments.append(name)

    def bone(segment: Segment, direction: float, rgba: tuple[float, float, float, float],
             offset: tuple[float, float] = (0.0, 0.0)) -> Shape:
        """A visual capsule along z from the joint (direction -1: downward)."""
        r = _capsule_radius(segment)
        length = max(segment.length_m - 2 * r, 0.01)
        return Shape("capsule", (r, length, 0.0), xyz=(offset[0], offset[1], direction * segment.length_m / 2),
                     rgba=rgba, collision=False)

    # base: the seat point (pinned to the throne)
    robot.add_link(Link("seat", Inertial(SEAT_MASS_KG, inertia=(1.0, 1.0, 1.0, 0.0, 0.0, 0.0))))
    hip_z = 0.09 * s
    hip_y = 0.05 * s
    pel = seg["pelvis"]
    segment_link("pelvis", pel, (0.0, 0.02 * s, hip_z + pel.com_from_proximal_m),
                 (Shape("box", (a.hip_width_m + 0.1 * s, 0.18 * s, pel.length_m + hip_z),
                        xyz=(0, 0.02 * s, (pel.length_m + hip_z) / 2), rgba=_TROUSERS, collision=False),))
    _add_3dof(robot, model, "seat", "seat", "pelvis", (0.0, 0.0, 0.0))
    abd = seg["abdomen"]
    segment_link("abdomen", abd, (0.0, 0.0, abd.com_from_proximal_m),
                 (Shape("box", (0.3 * s, 0.18 * s, abd.length_m), xyz=(0, 0.01 * s, abd.length_m / 2), rgba=_SHIRT,
                        collision=False),))
    _add_3dof(robot, model, "lumbar", "pelvis", "abdomen", (0.0, 0.0, hip_z + pel.length_m))
    tho = seg["thorax"]
    segment_link("thorax", tho, (0.0, 0.0, tho.com_from_proximal_m),
                 (Shape("box", (0.34 * s, 0.2 * s, tho.length_m), xyz=(0, 0.02 * s, tho.length_m / 2), rgba=_SHIRT,
                        collision=False),))
    _add_3dof(robot, model, "thoracic", "abdomen", "thorax", (0.0, 0.0, abd.length_m))
    neck = seg["neck"]
    segment_link("neck", neck, (0.0, 0.0, neck.com_from_proximal_m), (bone(neck, 1.0, _SKIN),))
    _add_3dof(robot, model, "neck", "thorax", "neck", (0.0, 0.0, tho.length_m))
    head = seg["head"]
    segment_link("head", head, (0.0, 0.02 * s, head.com_from_proximal_m),
                 (Shape("sphere", (0.1 * s, 0.0, 0.0), xyz=(0, 0.02 * s, head.com_from_proximal_m), rgba=_SKIN,
                        collision=False),))
    _add_3dof(robot, model, "head", "neck", "head", (0.0, 0.0, neck.length_m))

    for side in SIDES:
        sx = 1.0 if side == "right" else -1.0
        # shoulder girdle: sternoclavicular joint to the shoulder joint centre
        clav = seg["clavicle"]
        segment_link(f"{side}_clavicle", clav, (sx * clav.com_from_proximal_m, -0.025 * s, 0.01 * s),
                     (Shape("capsule", (0.02 * s, clav.length_m, 0.0),
                            xyz=(sx * clav.length_m / 2, -0.025 * s, 0.01 * s), rpy=(0.0, math.pi / 2, 0.0),
                            rgba=_SHIRT, collision=False),), long_axis="x")
        _add_3dof(robot, model, f"{side}_clavicle", "thorax", f"{side}_clavicle",
                  (sx * CLAVICLE_MIDLINE_OFFSET * s, 0.05 * s,
                   tho.length_m - (SHOULDER_BELOW_NECK + SHOULDER_ABOVE_STERNOCLAVICULAR) * s))
        ua, fa, hand = seg["upper_arm"], seg["forearm"], seg["hand"]
        segment_link(f"{side}_upper_arm", ua, (0.0, 0.0, -ua.com_from_proximal_m), (bone(ua, -1.0, _SHIRT),))
        _add_3dof(robot, model, f"{side}_shoulder", f"{side}_clavicle", f"{side}_upper_arm",
                  (sx * clav.length_m, -0.05 * s, SHOULDER_ABOVE_STERNOCLAVICULAR * s))
        segment_link(f"{side}_forearm", fa, (0.0, 0.0, -fa.com_from_proximal_m), (bone(fa, -1.0, _SKIN),))
        _add_3dof(robot, model, f"{side}_elbow", f"{side}_upper_arm", f"{side}_forearm", (0.0, 0.0, -ua.length_m))
        segment_link(f"{side}_hand", hand, (0.0, 0.0, -hand.com_from_proximal_m),
                     (Shape("box", (0.035 * s, 0.09 * s, hand.length_m), xyz=(0, 0.0, -hand.length_m / 2),
                            rgba=_SKIN, collision=False),))
        _add_3dof(robot, model, f"{side}_wrist", f"{side}_forearm", f"{side}_hand", (0.0, 0.0, -fa.length_m))
        # the stick: fulcrum between thumb and index, stick pointing forward; passive 2-axis fulcrum
        fulcrum = (0.0, 0.02 * s, -0.55 * hand.length_m)
        pitch_link = f"{side}_fulcrum"
        fingers = FULCRUM_ARMATURE_KGM2
        robot.add_link(Link(pitch_link, Inertial(DUMMY_MASS_KG, inertia=(fingers, fingers, fingers, 0.0, 0.0, 0.0))))
        tilt = STICK_GRIP_TILT_RAD  # the stick leaves the fist toward the fingers' side, not square to the hand
        robot.add_joint(Joint(f"{side}_fulcrum_x", "revolute", f"{side}_hand", pitch_link, xyz=fulcrum,
                              rpy=(-tilt, 0.0, 0.0), axis=(1.0, 0.0, 0.0), lower=-0.8, upper=0.8, effort=20.0,
                              velocity=100.0))
        spec.stick.add_to(robot, f"{side}_stick", pitch_link,
                          Joint(f"{side}_fulcrum_z", "revolute", pitch_link, f"{side}_stick", axis=(0.0, 0.0, 1.0),
                                lower=-0.8, upper=0.8, effort=20.0, velocity=100.0))
        model.passive += (f"{side}_fulcrum_x", f"{side}_fulcrum_z")
        model.segments.append(f"{side}_stick")
        # where the tip would be with the fingers at rest: the Cartesian controller's effector, so the
        # fulcrum's fast passive oscillation stays out of its feedback loop
        aim = f"{side}_stick_aim"
        robot.add_link(Link(aim, Inertial(1e-4, inertia=(1e-9, 1e-9, 1e-9, 0.0, 0.0, 0.0))))
        robot.add_joint(Joint(f"{aim}_joint", "fixed", f"{side}_hand", aim,
                              xyz=(fulcrum[0], fulcrum[1] + spec.stick.tip_offset * math.cos(tilt),
                                   fulcrum[2] - spec.stick.tip_offset * math.sin(tilt))))
        model.effectors[f"{side}_hand"] = aim
        model.tips[f"{side}_hand"] = f"{side}_stick_tip"

        # the leg: its own multibody, based on the throne at the hip joint centre (see the module docstring)
        leg = Robot(f"percussionist_{side}_leg")
        mount = f"{side}_hip_mount"
        leg.add_link(Link(mount, Inertial(SEAT_MASS_KG / 2, inertia=(0.5, 0.5, 0.5, 0.0, 0.0, 0.0))))
        model.parts.append(BodyPart(leg, (sx * a.hip_width_m / 2, hip_y, hip_z)))
        th, sh, foot = seg["thigh"], seg["shank"], seg["foot"]
        segment_link(f"{side}_thigh", th, (0.0, 0.0, -th.com_from_proximal_m), (bone(th, -1.0, _TROUSERS),),
                     robot=leg)
        _add_3dof(leg, model, f"{side}_hip", mount, f"{side}_thigh", (0.0, 0.0, 0.0))
        segment_link(f"{side}_shank", sh, (0.0, 0.0, -sh.com_from_proximal_m), (bone(sh, -1.0, _TROUSERS),),
                     robot=leg)
        _add_3dof(leg, model, f"{side}_knee", f"{side}_thigh", f"{side}_shank", (0.0, 0.0, -th.length_m))
        heel_y, sole_z = -0.045 * s, -0.08 * s
        segment_link(f"{side}_foot", foot, (0.0, heel_y + foot.com_from_proximal_m, sole_z + 0.03 * s),
                     (Shape("box", (0.09 * s, foot.length_m, 0.05 * s),
                            xyz=(0.0, heel_y + foot.length_m / 2, sole_z + 0.025 * s), rgba=_DARK_SHOE),),
                     long_axis="y", robot=leg)
        _add_3dof(leg, model, f"{side}_ankle", f"{side}_shank", f"{side}_foot", (0.0, 0.0, -sh.length_m))
        ball = f"{side}_foot_ball"
        leg.add_link(Link(ball, Inertial(1e-4, inertia=(1e-9, 1e-9, 1e-9, 0.0, 0.0, 0.0))))
        leg.add_joint(Joint(f"{ball}_joint", "fixed", f"{side}_foot", ball,
                            xyz=(0.0, heel_y + 0.72 * foot.length_m, sole_z)))
        model.effectors[f"{side}_foot"] = ball
        model.tips[f"{side}_foot"] = ball
    return model


_DARK_SHOE = (0.1, 0.1, 0.1, 1.0)
