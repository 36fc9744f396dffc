"""The pose editor's model (2001 paper's poser GUI): joint angles on the stick figure, forward kinematics.

The figure's rest pose is the synthetic drummer's (:mod:`services.graphics.figure`)
with its constant link offsets; each joint gets three extra angles (degrees,
intrinsic x-y-z in the joint's own frame) from the page's sliders. UP/DOWN key
poses are saved as ``{name: {joint: [rx, ry, rz]}}`` in a YAML file (by
default ``poses.yaml`` in the editor's directory), which the keyframe
animation (``common.gesture``) can read.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Field, field_validator
from scipy.spatial.transform import Rotation

from services.graphics.figure import LINK_NAMES, SyntheticDrummer
from services.graphics.skeleton import guess_parents

POSE_NAME = re.compile(r"^[A-Za-z0-9_]+(\.[A-Za-z0-9_]+)*$")
Angles = tuple[float, float, float]


class PoseLibrary(BaseModel):
    """Named key poses: pose name -> joint -> (rx, ry, rz) degrees."""

    model_config = ConfigDict(extra="forbid")

    poses: dict[str, dict[str, Angles]] = Field(default_factory=dict)

    @field_validator("poses")
    @classmethod
    def _check(cls, value: dict[str, dict[str, Angles]]) -> dict[str, dict[str, Angles]]:
        for name, joints in value.items():
            if not POSE_NAME.match(name):
                raise ValueError(f"pose name {name!r}: letters, digits, '_' and '.' only (e.g. SNARE.left_hand.UP)")
            for joint, angles in joints.items():
                if joint not in LINK_NAMES:
                    raise ValueError(f"pose {name!r}: unknown joint {joint!r}")
                if any(not -360 <= a <= 360 for a in angles):
                    raise ValueError(f"pose {name!r}: angles of {joint!r} must be within +-360 degrees")
        return value

    @classmethod
    def load(cls, path: Path) -> PoseLibrary:
        if not path.is_file():
            return cls()
        return cls.model_validate({"poses": yaml.safe_load(path.read_text(encoding="utf-8")) or {}})

    def save(self, path: Path) -> None:
        data = {name: {j: [float(a) for a in ang] for j, ang in joints.items()} for name, joints in self.poses.items()}
        path.write_text(yaml.safe_dump(data, sort_keys=True), encoding="utf-8")


class Poser:
    """Forward kinematics of the stick figure from per-joint angle offsets."""

    def __init__(self) -> None:
        rest = SyntheticDrummer(strokes={}, duration=0.0).pose(0.0)
        self.names = list(LINK_NAMES)
        self.parents = guess_parents(self.names)
        self.root_position = rest[0, :3].copy()
        self.root_rotation = Rotation.from_quat(rest[0, 3:])
        world = [Rotation.from_quat(q) for q in rest[:, 3:]]
        self.local: list[Rotation] = []
        self.offsets = np.zeros((len(self.names), 3))
        for i, parent in enumerate(self.parents):
            if parent < 0:
                self.local.append(world[i])
                continue
            self.local.append(world[parent].inv() * world[i])
            self.offsets[i] = world[parent].inv().apply(rest[i, :3] - rest[parent, :3])
        # joints the sliders move: every link except the stick parts and the tip of the foot
        self.joints = [n for n in self.names if not n.endswith(("stick", "stick_tip", "toe"))]

    def pose(self, angles: dict[str, Angles] | None = None) -> np.ndarray:
        """World poses (L, 7) with ``angles`` (joint -> degrees) added to the rest pose."""
        angles = angles or {}
        out = np.zeros((len(self.names), 7))
        world: list[Rotation] = []
        for i, parent in enumerate(self.parents):
            extra = Rotation.from_euler("XYZ", angles.get(self.names[i], (0.0, 0.0, 0.0)), degrees=True)
            if parent < 0:
                rot = self.local[i] * extra
                pos = self.root_position
            else:
                rot = world[parent] * self.local[i] * extra
                pos = out[parent, :3] + world[parent].apply(self.offsets[i])
            world.append(rot)
            out[i, :3] = pos
            out[i, 3:] = rot.as_quat()
        return out

    @staticmethod
    def clean(angles: object) -> dict[str, Angles]:
        """Validate angles sent by the page; ``ValueError`` when malformed."""
        if not isinstance(angles, dict):
            raise ValueError("angles must be an object {joint: [rx, ry, rz]}")
        return PoseLibrary.model_validate({"poses": {"edit": angles}}).poses["edit"]
