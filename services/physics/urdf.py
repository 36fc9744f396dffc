"""Generate URDF in code: links with mass, centre of mass, inertia and shapes; joints.

Every body in the physics world (character, sticks, kit pieces) is described
with these dataclasses and serialised to URDF text, so nothing is hand-written
and the same description can be saved for inspection (``Robot.to_xml``).
Units: metres, kilograms, kg m^2, radians, newton-metres.
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass, field
from typing import Literal
from xml.sax.saxutils import escape

Vec3 = tuple[float, float, float]

ShapeKind = Literal["box", "cylinder", "sphere", "capsule"]


@dataclass(frozen=True)
class Shape:
    """A collision and/or visual primitive in a link's frame.

    ``size``, metres: a box's full edge lengths (x, y, z); a cylinder's or
    capsule's (radius, length, 0) with its axis on local z; a sphere's
    (radius, 0, 0).
    """

    kind: ShapeKind
    size: Vec3
    xyz: Vec3 = (0.0, 0.0, 0.0)
    rpy: Vec3 = (0.0, 0.0, 0.0)
    collision: bool = True
    visual: bool = True
    rgba: tuple[float, float, float, float] = (0.8, 0.8, 0.8, 1.0)

    def geometry_xml(self) -> str:
        a, b, c = self.size
        if self.kind == "box":
            return f'<box size="{a:.6g} {b:.6g} {c:.6g}"/>'
        if self.kind == "cylinder":
            return f'<cylinder radius="{a:.6g}" length="{b:.6g}"/>'
        if self.kind == "capsule":
            return f'<capsule radius="{a:.6g}" length="{b:.6g}"/>'
        return f'<sphere radius="{a:.6g}"/>'


@dataclass(frozen=True)
class Inertial:
    """Mass (kg), centre of mass (m, link frame) and inertia about the COM (kg m^2, link axes)."""

    mass: float
    com: Vec3 = (0.0, 0.0, 0.0)
    inertia: tuple[float, float, float, float, float, float] = (1e-6, 1e-6, 1e-6, 0.0, 0.0, 0.0)
    """(ixx, iyy, izz, ixy, ixz, iyz)."""


@dataclass(frozen=True)
class Link:
    name: str
    inertial: Inertial
    shapes: tuple[Shape, ...] = ()


JointKind = Literal["revolute", "continuous", "prismatic", "fixed"]


@dataclass(frozen=True)
class Joint:
    """A joint from ``parent`` to ``child``; ``xyz``/``rpy`` place the child frame in the parent frame."""

    name: str
    kind: JointKind
    parent: str
    child: str
    xyz: Vec3 = (0.0, 0.0, 0.0)
    rpy: Vec3 = (0.0, 0.0, 0.0)
    axis: Vec3 = (0.0, 0.0, 1.0)
    lower: float = 0.0
    upper: float = 0.0
    effort: float = 0.0
    velocity: float = 0.0
    damping: float = 0.0


@dataclass
class Robot:
    """A tree of links and joints, serialised to URDF."""

    name: str
    links: list[Link] = field(default_factory=list)
    joints: list[Joint] = field(default_factory=list)

    def add_link(self, link: Link) -> Link:
        if any(existing.name == link.name for existing in self.links):
            raise ValueError(f"duplicate link name {link.name!r}")
        self.links.append(link)
        return link

    def add_joint(self, joint: Joint) -> Joint:
        names = {lk.name for lk in self.links}
        if joint.parent not in names or joint.child not in names:
            raise ValueError(f"joint {joint.name!r} connects unknown links {joint.parent!r} -> {joint.child!r}")
        self.joints.append(joint)
        return joint

    def to_xml(self) -> str:
        out = [f'<?xml version="1.0"?>\n<robot name="{escape(self.name)}">']
        for link in self.links:
            out.append(_link_xml(link))
        for joint in self.joints:
            out.append(_joint_xml(joint))
        out.append("</robot>\n")
        return "\n".join(out)


def _v(v: Vec3) -> str:
    return f"{v[0]:.9g} {v[1]:.9g} {v[2]:.9g}"


def _link_xml(link: Link) -> str:
    i = link.inertial
    ixx, iyy, izz, ixy, ixz, iyz = i.inertia
    parts = [
        f'<link name="{escape(link.name)}">',
        f'<inertial><origin xyz="{_v(i.com)}" rpy="0 0 0"/><mass value="{i.mass:.9g}"/>'
        f'<inertia ixx="{ixx:.9g}" iyy="{iyy:.9g}" izz="{izz:.9g}" ixy="{ixy:.9g}" ixz="{ixz:.9g}" iyz="{iyz:.9g}"/>'
        "</inertial>",
    ]
    for s in link.shapes:
        origin = f'<origin xyz="{_v(s.xyz)}" rpy="{_v(s.rpy)}"/>'
        geometry = f"<geometry>{s.geometry_xml()}</geometry>"
        if s.visual:
            r, g, b, a = s.rgba
            parts.append(
                f"<visual>{origin}{geometry}<material name=\"m\"><color rgba=\"{r:.3g} {g:.3g} {b:.3g} {a:.3g}\"/>"
                "</material></visual>"
            )
        if s.collision:
            parts.append(f"<collision>{origin}{geometry}</collision>")
    parts.append("</link>")
    return "".join(parts)


def _joint_xml(j: Joint) -> str:
    parts = [
        f'<joint name="{escape(j.name)}" type="{j.kind}">',
        f'<parent link="{escape(j.parent)}"/><child link="{escape(j.child)}"/>',
        f'<origin xyz="{_v(j.xyz)}" rpy="{_v(j.rpy)}"/>',
    ]
    if j.kind != "fixed":
        parts.append(f'<axis xyz="{_v(j.axis)}"/>')
        parts.append(f'<limit lower="{j.lower:.9g}" upper="{j.upper:.9g}" effort="{j.effort:.9g}" '
                     f'velocity="{j.velocity:.9g}"/>')
        parts.append(f'<dynamics damping="{j.damping:.9g}" friction="0"/>')
    parts.append("</joint>")
    return "".join(parts)


def box_inertia(mass: float, x: float, y: float, z: float) -> tuple[float, float, float, float, float, float]:
    """Inertia of a solid box of edge lengths x, y, z metres about its centre (kg m^2)."""
    return (
        mass * (y * y + z * z) / 12.0,
        mass * (x * x + z * z) / 12.0,
        mass * (x * x + y * y) / 12.0,
        0.0,
        0.0,
        0.0,
    )


def cylinder_inertia(mass: float, radius: float, length: float) -> tuple[float, float, float, float, float, float]:
    """Inertia of a solid cylinder, axis on z, about its centre (kg m^2)."""
    side = mass * (3.0 * radius * radius + length * length) / 12.0
    return (side, side, 0.5 * mass * radius * radius, 0.0, 0.0, 0.0)


def load_robot(client: object, robot: Robot, base_xyz: Vec3, base_quat: tuple[float, float, float, float],
               fixed_base: bool, flags: int = 0) -> int:
    """Write ``robot`` to a temporary URDF file and load it into a PyBullet client; returns the body id.

    PyBullet gives every link a collision object, with no shape where the URDF has none (the 3-DOF joints'
    dummy links, most of the body's segments): those are taken out of collision detection, whose broadphase
    would otherwise pair them with everything near them at every step."""
    xml = robot.to_xml()
    fd, path = tempfile.mkstemp(suffix=".urdf", prefix=f"batteur_{robot.name}_")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(xml)
        body: int = client.loadURDF(  # type: ignore[attr-defined]
            path, basePosition=base_xyz, baseOrientation=base_quat, useFixedBase=fixed_base, flags=flags
        )
    finally:
        os.unlink(path)
    shapeless = {link.name for link in robot.links if not any(shape.collision for shape in link.shapes)}
    if client.getBodyInfo(body)[0].decode() in shapeless:  # type: ignore[attr-defined]
        client.setCollisionFilterGroupMask(body, -1, 0, 0)  # type: ignore[attr-defined]
    for j in range(client.getNumJoints(body)):  # type: ignore[attr-defined]
        if client.getJointInfo(body, j)[12].decode() in shapeless:  # type: ignore[attr-defined]
            client.setCollisionFilterGroupMask(body, j, 0, 0)  # type: ignore[attr-defined]
    return body
