"""Drumsticks: geometry, mass, and the links that carry them.

A stick link's frame has its origin at the fulcrum (where the hand holds it)
and the stick along local +y; the butt is at -grip, the tip bead's centre at
``tip_offset``. The tip bead is a collision sphere on the stick link itself (a
separate light collision link lets the tip sink into compliant heads); a
massless, collision-free ``tip`` marker link sits at the bead centre for
kinematics (Jacobians, IK targets, poses).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from services.physics.urdf import Inertial, Joint, Link, Robot, Shape

_WOOD = (0.85, 0.7, 0.45, 1.0)


@dataclass(frozen=True)
class StickSpec:
    """A drumstick (defaults: a 5A hickory stick).

    ``length_m``: overall length; ``radius_m``: shaft radius; ``mass_kg``;
    ``tip_radius_m``: radius of the bead; ``grip_m``: fulcrum distance from
    the butt (about a third of the length).
    """

    length_m: float = 0.406
    radius_m: float = 0.0073
    mass_kg: float = 0.045
    tip_radius_m: float = 0.0065
    grip_m: float = 0.13

    @property
    def tip_offset(self) -> float:
        """Distance fulcrum -> tip bead centre, metres."""
        return self.length_m - self.grip_m - self.tip_radius_m

    @property
    def com_offset(self) -> float:
        """Distance fulcrum -> centre of mass along +y, metres (uniform shaft)."""
        return self.length_m / 2 - self.grip_m

    def inertia_about_com(self) -> tuple[float, float, float, float, float, float]:
        m, length, r = self.mass_kg, self.length_m, self.radius_m
        side = m * (3 * r * r + length * length) / 12
        return (side, 0.5 * m * r * r, side, 0.0, 0.0, 0.0)

    def shapes(self) -> tuple[Shape, ...]:
        """Shaft capsule (stopping short of the bead) and the tip bead, in the stick frame."""
        shaft_start = -self.grip_m + self.radius_m
        shaft_end = self.tip_offset - 2.5 * self.tip_radius_m
        shaft_len = shaft_end - shaft_start
        mid = (shaft_start + shaft_end) / 2
        # a thinner neck stands in for the taper, so the bead touches first
        return (
            Shape("capsule", (self.radius_m * 0.85, shaft_len, 0.0), xyz=(0, mid, 0), rpy=(math.pi / 2, 0, 0),
                  rgba=_WOOD),
            Shape("sphere", (self.tip_radius_m, 0.0, 0.0), xyz=(0, self.tip_offset, 0), rgba=_WOOD),
        )

    def add_to(self, robot: Robot, name: str, parent: str, joint: Joint | None = None) -> tuple[str, str]:
        """Add the stick link ``name`` (and ``name``_tip marker) to ``robot`` under ``parent``.

        ``joint``: how the stick attaches (default: a fixed joint at the parent's origin).
        Returns (stick link name, tip link name).
        """
        robot.add_link(Link(name, Inertial(self.mass_kg, com=(0, self.com_offset, 0),
                                           inertia=self.inertia_about_com()), self.shapes()))
        if joint is None:
            joint = Joint(f"{name}_grip", "fixed", parent, name)
        robot.add_joint(joint)
        tip = f"{name}_tip"
        robot.add_link(Link(tip, Inertial(1e-4, inertia=(1e-9, 1e-9, 1e-9, 0, 0, 0))))
        robot.add_joint(Joint(f"{tip}_joint", "fixed", name, tip, xyz=(0, self.tip_offset, 0)))
        return name, tip

    def part(self, side: str, distance_from_tip_m: float) -> str:
        """Striker part name of a contact ``distance_from_tip_m`` from the bead centre."""
        return f"{side}_stick_tip" if distance_from_tip_m <= 2.5 * self.tip_radius_m else f"{side}_stick_shaft"
