"""The physics node: :class:`~services.physics.core.PhysicsCore` live over UDP, locked to the rig clock.

    batteur physics                                   # the drummer at the default kit, 1 kHz
    batteur physics --scene strike --strike-period 0.5 --strike-velocity 3
    batteur physics --kit double_pedal --left-handed --control joint_pd --grip german

Contacts go to ``interaction`` every step while in contact; poses to
``graphics`` at ``--pose-rate-hz``. Targets, control mode, gains, grip and
reset arrive as /batteur/physics/... messages (docs/physics.md).
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from typing import Literal

from pydantic import Field

from common.config import NodeSettings
from common.kit import EventType
from common.messages.physics import ControlModeName
from common.runtime import run_node
from services.physics.core import PhysicsCore, PhysicsSettings


class PhysicsNodeSettings(NodeSettings):
    """Node settings plus the physics service's own (flags, BATTEUR_* variables, settings file keys)."""

    scene: Literal["strike", "drummer"] = Field(default="drummer", description="strike: one stick over one "
                                                "instrument (integration); drummer: the 57-DOF percussionist")
    kit: str = Field(default="default", min_length=1, description="kit name or kit file (YAML or JSON)")
    left_handed: bool = Field(default=False, description="mirror the kit for a left-handed drummer")
    control: ControlModeName = Field(default="cartesian",
                                                                   description="controller at start")
    grip: Literal["french", "german", "american", "traditional"] = Field(default="american",
                                                                         description="grip at start")
    height_m: float = Field(default=1.75, ge=1.2, le=2.2, description="drummer's height, metres")
    mass_kg: float = Field(default=73.0, ge=35, le=150, description="drummer's mass, kilograms")
    pose_rate_hz: float = Field(default=60.0, ge=0, le=240, description="pose publishing rate, Hz")
    strike_event: EventType = Field(default=EventType.SNARE, description="strike scene: the event's hit point")
    strike_period: float = Field(default=0.0, ge=0, le=60,
                                 description="strike scene: strike every this many seconds (0: only on request)")
    strike_velocity: float = Field(default=3.0, gt=0, le=30, description="strike scene: tip speed, m/s")


def make_core(settings: NodeSettings, extra: argparse.Namespace) -> PhysicsCore:
    """Build the core (live mode); ValueError (printed, exit 2) for a bad kit or setting."""
    if not isinstance(settings, PhysicsNodeSettings):
        settings = PhysicsNodeSettings.model_validate(settings.model_dump())
    try:
        core_settings = PhysicsSettings(
            scene=settings.scene,
            mode="live",
            rate_hz=settings.rate_hz or 1000.0,
            pose_rate_hz=settings.pose_rate_hz,
            kit=settings.kit,
            left_handed=settings.left_handed,
            strike_event=settings.strike_event,
            control=settings.control,
            grip=settings.grip,
            height_m=settings.height_m,
            mass_kg=settings.mass_kg,
            strike_period_s=settings.strike_period,
            strike_velocity=settings.strike_velocity,
        )
        return PhysicsCore(core_settings)
    except FileNotFoundError as exc:
        raise ValueError(str(exc)) from None


def main(argv: Sequence[str] | None = None) -> int:
    return run_node(
        "physics",
        make_core,
        argv,
        description="Batteur physics: the simulated percussionist and kit (PyBullet), contacts and poses.",
        settings_cls=PhysicsNodeSettings,
    )


if __name__ == "__main__":
    raise SystemExit(main())
