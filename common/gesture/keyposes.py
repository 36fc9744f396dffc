"""Key poses saved by the pose editor (the 2001 paper's poser GUI) for the keyframe mode: ``poses.yaml``.

A key pose is a posture of the 57-DOF percussionist (joint angles in degrees,
the 19 joints of :mod:`common.character`) and where it puts the effectors
(stick tips and feet, metres, kit frame), which the editor computes by forward
kinematics when it saves. The keyframe mode (:mod:`common.gesture.keyframe`)
reads the poses named ``EVENT.limb.UP`` and ``EVENT.limb.DOWN`` (e.g.
``SNARE.left_hand.UP``): the effector's move from DOWN (the stick on the head)
to UP is the preparation of a full-velocity stroke of that limb on that event.
Without them (no file, or no pose for that event and limb) the shipped default
applies: the tip raised along the surface normal. File format::

    SNARE.left_hand.UP:
      joints: {left_shoulder: [40.0, -10.0, 0.0], left_elbow: [75.0, 0.0, -45.0], ...}
      effectors: {left_hand: [-0.12, 0.30, 0.98], right_hand: [...], left_foot: [...], right_foot: [...]}
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Literal

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from common.character import JOINTS
from common.datafile import parse_file
from common.input_file import NO_SUCH_FILE, file_problem
from common.kit import EventType, Limb
from common.output_paths import write_atomically

POSE_NAME = re.compile(r"^[A-Za-z0-9_]+(\.[A-Za-z0-9_]+)*$")
MIN_LIFT_M = 0.01
"""An UP pose whose effector is closer than this to the DOWN pose's does not define a lift (metres)."""
Angles = tuple[float, float, float]
Point = tuple[float, float, float]


class KeyPose(BaseModel):
    """One saved posture: joint angles (degrees, intrinsic x-y-z) and the effector positions it gives (metres)."""

    model_config = ConfigDict(extra="forbid")

    joints: dict[str, Angles] = Field(default_factory=dict, description="joint -> (x, y, z) degrees")
    effectors: dict[Limb, Point] = Field(default_factory=dict, description="limb -> stick tip / foot, metres")

    @field_validator("joints")
    @classmethod
    def _joints(cls, value: dict[str, Angles]) -> dict[str, Angles]:
        for joint, angles in value.items():
            if joint not in JOINTS:
                raise ValueError(f"unknown joint {joint!r} (the 19 joints: {', '.join(JOINTS)})")
            if not all(math.isfinite(a) and -360 <= a <= 360 for a in angles):
                raise ValueError(f"angles of {joint!r} must be finite and within +-360 degrees")
        return value

    @field_validator("effectors")
    @classmethod
    def _effectors(cls, value: dict[Limb, Point]) -> dict[Limb, Point]:
        for limb, point in value.items():
            if not all(math.isfinite(c) and abs(c) <= 5 for c in point):
                raise ValueError(f"effector {limb.value} must be finite and within 5 m of the drummer")
        return value


class KeyPoses(BaseModel):
    """Named key poses (the content of ``poses.yaml``); empty = the shipped defaults everywhere."""

    model_config = ConfigDict(extra="forbid")

    poses: dict[str, KeyPose] = Field(default_factory=dict)

    @field_validator("poses")
    @classmethod
    def _names(cls, value: dict[str, KeyPose]) -> dict[str, KeyPose]:
        for name in value:
            if not POSE_NAME.fullmatch(name):
                raise ValueError(f"pose name {name!r}: letters, digits, '_' and '.' only (e.g. SNARE.left_hand.UP)")
        return value

    @classmethod
    def load(cls, path: Path | str | None) -> KeyPoses:
        """Read a poses file; no path or no file: the defaults. ``ValueError`` naming the file when invalid, or when
        it is not a regular file (a folder, a device, a pipe: never opened, a pipe would wait for a writer)."""
        problem = None if path is None else file_problem(Path(path), "a poses file (YAML)")
        if path is None or problem == NO_SUCH_FILE:
            return cls()
        if problem is not None:
            raise ValueError(f"{path}: {problem}")
        try:
            data = parse_file(Path(path)) or {}
            return cls.model_validate({"poses": data})
        except ValidationError as exc:
            first = exc.errors()[0]
            where = ".".join(str(p) for p in first.get("loc", ())[1:])
            detail = f"{first.get('msg')} (at {where or 'top level'})"
            raise ValueError(f"{path}: not a valid poses file: {detail}") from None
        except ValueError as exc:  # not UTF-8 text, not YAML
            raise ValueError(f"{path}: not a valid poses file: {exc}") from None

    def save(self, path: Path) -> None:
        """Write the poses as YAML, whole or not at all (a crash or a full disk leaves the earlier file)."""
        text = yaml.safe_dump(self.model_dump(mode="json")["poses"], sort_keys=True)
        write_atomically(path, text.encode("utf-8"))

    def with_pose(self, name: str, pose: KeyPose) -> KeyPoses:
        """A copy with ``name`` added or replaced (validated)."""
        return KeyPoses.model_validate({"poses": {**self.poses, name: pose}})

    def key(self, event: EventType | str, limb: Limb | str, which: Literal["UP", "DOWN"]) -> KeyPose | None:
        return self.poses.get(f"{EventType(event).value}.{Limb(limb).value}.{which}")

    def lift(self, event: EventType | str, limb: Limb | str) -> np.ndarray | None:
        """The effector's move DOWN -> UP of ``limb`` on ``event`` (3,) metres, or None (default: the normal)."""
        limb = Limb(limb)
        up, down = self.key(event, limb, "UP"), self.key(event, limb, "DOWN")
        if up is None or down is None or limb not in up.effectors or limb not in down.effectors:
            return None
        vec = np.asarray(up.effectors[limb], dtype=float) - np.asarray(down.effectors[limb], dtype=float)
        return vec if float(np.linalg.norm(vec)) >= MIN_LIFT_M else None
