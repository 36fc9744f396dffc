"""Control messages of the physics service (/batteur/physics/...).

Targets are streamed ahead of time: each carries the rig time at which the
limb (or the joints) should be there, and the velocity it should have then.
The physics service interpolates between received targets (cubic Hermite),
so a sender can stream at any rate (the 250 Hz of motion capture, or sparse
key frames). Targets in the past, non-finite values, unreachable positions and
wrong lengths are rejected with a clear error, counted and answered to the
sender (:class:`PhysicsRejected`).
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from common.messages.base import Family, OscMessage, RigTime
from common.messages.registry import register

ControlModeName = Literal["joint_pd", "joint_spd", "joint_ct", "cartesian", "cartesian_pd"]
"""joint_pd: explicit PD torques (the paper's); joint_spd: stable PD (Tan et al. 2011); joint_ct: PD through inverse
dynamics (computed torque); cartesian: damped least squares IK feeding the computed-torque PD; cartesian_pd:
the same IK feeding the explicit PD (the paper's Algorithm 2 as written)."""

GripName = Literal["french", "german", "american", "traditional"]
"""french: palms facing, thumbs up; german: palms down; american: matched, in between; traditional: the snare hand
underhand (the hand that does not lead: the left on a right-handed kit, the right on a left-handed one), the other as
american."""

LimbName = Literal["left_hand", "right_hand", "left_foot", "right_foot"]
JointGroup = Literal["all", "trunk", "head", "arms", "legs"]


@register
class PhysicsControlMode(OscMessage):
    """Switch the controller live."""

    ADDRESS = "/batteur/physics/control"
    FAMILY = Family.CONTROL

    mode: ControlModeName = Field(description="joint_pd, joint_spd (stable PD), joint_ct (computed torque), "
                                  "cartesian (DLS IK -> computed torque) or cartesian_pd (DLS IK -> explicit PD)")


@register
class PhysicsGains(OscMessage):
    """Scale the PD gains of a joint group (1 = the mass-scaled defaults)."""

    ADDRESS = "/batteur/physics/gains"
    FAMILY = Family.CONTROL

    group: JointGroup = Field(description="joints affected: all, trunk, head, arms, legs")
    ks_scale: float = Field(ge=0, le=20, description="stiffness multiplier (ks, N m/rad, relative to default)")
    kd_scale: float = Field(ge=0, le=20, description="damping multiplier (kd, N m s/rad, relative to default)")


@register
class PhysicsGrip(OscMessage):
    """Change how a hand holds its stick."""

    ADDRESS = "/batteur/physics/grip"
    FAMILY = Family.CONTROL

    hand: Literal["left", "right", "both"] = Field(description="which hand")
    grip: GripName = Field(description="french, german, american or traditional (american: a matched grip, the "
                           "palms between french and german; traditional: the snare hand underhand, the left on a "
                           "right-handed kit, the right on a left-handed one)")


@register
class PhysicsIk(OscMessage):
    """Parameters of the Cartesian controller (damped least squares, Algorithm 2)."""

    ADDRESS = "/batteur/physics/ik"
    FAMILY = Family.CONTROL

    damping: float = Field(ge=0, le=1, description="DLS damping lambda, metres")
    posture_gain: float = Field(ge=0, le=10, description="null-space pull toward the rest posture, 1/s")


@register
class PhysicsReset(OscMessage):
    """Put the drummer back in the rest posture and clear every queued target (at once: a score plan being
    computed is dropped)."""

    ADDRESS = "/batteur/physics/reset"
    FAMILY = Family.CONTROL

    time: RigTime = Field(description="rig time of the request, seconds (informational)")


@register
class PhysicsStrike(OscMessage):
    """Strike scene only: drive the test stick onto its instrument at a given time and velocity."""

    ADDRESS = "/batteur/physics/strike"
    FAMILY = Family.CONTROL

    time: RigTime = Field(description="rig time of contact, seconds")
    velocity: float = Field(gt=0, le=30, description="stick tip speed at contact, m/s")


@register
class CartesianTarget(OscMessage):
    """Where a stick tip or foot should be at a time, and its velocity there (world frame)."""

    ADDRESS = "/batteur/physics/target"
    FAMILY = Family.CONTROL

    limb: LimbName = Field(description="left_hand/right_hand: stick tip; left_foot/right_foot: ball of the foot")
    time: RigTime = Field(description="rig time of this waypoint, seconds")
    x: float = Field(ge=-5, le=5, description="position x, metres")
    y: float = Field(ge=-5, le=5, description="position y, metres")
    z: float = Field(ge=-1, le=5, description="position z, metres")
    vx: float = Field(ge=-50, le=50, description="velocity x, m/s")
    vy: float = Field(ge=-50, le=50, description="velocity y, m/s")
    vz: float = Field(ge=-50, le=50, description="velocity z, m/s")


@register
class JointTarget(OscMessage):
    """All actuated joints at a time: 57 angles (rad) then 57 velocities (rad/s), in skeleton DOF order."""

    ADDRESS = "/batteur/physics/joints"
    FAMILY = Family.CONTROL

    time: RigTime = Field(description="rig time of this waypoint, seconds")
    values: tuple[float, ...] = Field(description="57 joint angles, radians, then 57 joint velocities, rad/s")


@register
class PhysicsPosture(OscMessage):
    """Drummer scene: glide every joint to a posture and hold it (the graphics pose editor sends it).

    Physics clamps the angles into its joint limits, moves from the current target
    to the posture over ``duration`` seconds from ``max(time, now)`` (cubic, zero
    velocity at both ends) and holds it until the next posture or /batteur/physics/reset.
    """

    ADDRESS = "/batteur/physics/posture"
    FAMILY = Family.CONTROL

    time: RigTime = Field(description="rig time the move starts (a past time: at once), seconds")
    duration: float = Field(ge=0, le=10, description="time to reach the posture, seconds")
    values: tuple[float, ...] = Field(description="57 joint angles, radians, in skeleton DOF order "
                                      "(common/character.py DOF_NAMES)")


@register
class PhysicsRejected(OscMessage):
    """Reply to a physics or score control message (/batteur/physics/..., /batteur/score/...) that was refused, and
    why, sent back to its sender: a target out of reach, a strike outside the strike scene, a score that cannot be
    read or played, a pause with nothing playing, a live note too late to prepare ...; also a message the node
    could not decode (a wrong argument count or type, a value out of range), or another service's control sent to a
    physics node (naming the service that takes it). Accepted messages get no answer.
    Budgeted per sender host, past it counted and not answered: the physics core's refusals 20 at once, then 10 a
    second; the node's, for a message it could not decode or another service's control, 10 at once, then 5 a
    second."""

    ADDRESS = "/batteur/physics/rejected"
    FAMILY = Family.CONTROL

    address: str = Field(max_length=128, description="address of the refused message")
    reason: str = Field(max_length=512, description="why it was refused")
