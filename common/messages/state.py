"""State messages: what the body and kit look like, published at the graphics rate."""

from __future__ import annotations

from typing import Annotated

from pydantic import Field

from common.messages.base import Family, OscMessage, RigTime
from common.messages.registry import register

LinkName = Annotated[str, Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.-]+$")]


@register
class Skeleton(OscMessage):
    """Names of the links whose poses follow in /batteur/pose, in order.

    Sent by physics at start, on every hello from a new peer, and every few
    seconds, so a late joiner learns the layout.
    """

    ADDRESS = "/batteur/skeleton"
    FAMILY = Family.STATE

    layout: int = Field(ge=0, description="layout id; /batteur/pose carries the same id")
    names: tuple[LinkName, ...] = Field(description="link names, one per pose block")


@register
class Pose(OscMessage):
    """Poses of every link at one instant: 7 floats per link (x y z qx qy qz qw).

    Positions in metres (world frame), orientations as unit quaternions.
    """

    ADDRESS = "/batteur/pose"
    FAMILY = Family.STATE

    time: RigTime = Field(description="rig time of the pose, seconds")
    layout: int = Field(ge=0, description="layout id from /batteur/skeleton")
    values: tuple[float, ...] = Field(description="x y z qx qy qz qw per link, metres / quaternion")
