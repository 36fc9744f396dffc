"""The 3D view's camera presets and default camera: one table for the page, the core, the video and the Pd panel.

Frame: metres, z up, the drummer at the origin facing +y. An orbit camera
looks at ``target`` from ``distance`` metres away, ``azimuth_deg`` about the
vertical (0: in front of the kit, +y, looking at the drummer; 90: from the
drummer's right, +x) and ``elevation_deg`` above the horizon
(:func:`camera_eye`). The page gets :func:`presets_json` in every ``view``
message and places its camera from it, so a preset looks the same in the
browser, in ``batteur render --video`` and in what the core and the Pd panel
report. Light on purpose (no numpy): ``pd/make_control.py`` imports it.
"""

from __future__ import annotations

import math
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from common.messages.graphics import CameraPreset

Vec3 = tuple[float, float, float]
TARGET: Vec3 = (0.0, 0.35, 0.75)
"""What the orbit presets look at, metres: the middle of the kit, a little above the snare."""


class CameraView(BaseModel):
    """One preset: an orbit about ``target``, or (``eye`` set) a camera fixed at ``eye`` looking at ``target``."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    azimuth_deg: float = Field(description="about the vertical, degrees: 0 from +y (the front), 90 from +x")
    elevation_deg: float = Field(description="above the horizon, degrees")
    distance: float = Field(gt=0, description="from the target, metres")
    target: Vec3 = Field(default=TARGET, description="look-at point, metres")
    eye: Vec3 | None = Field(default=None, description="fixed camera position (metres) instead of the orbit")
    turn_deg_per_s: float = Field(default=0.0, description="azimuth turning rate (orbit preset), degrees/second")


DRUMMER_EYES: Vec3 = (-0.16, -0.10, 1.30)
"""Where physics' drummer's eyes are, metres: 8 cm in front of the centre of its head at rest
(``character.json``: the head leans back and to the left, toward the hi-hat), rounded to the centimetre."""


def camera_eye(azimuth_deg: float, elevation_deg: float, distance: float, target: Vec3) -> Vec3:
    """Camera position (metres) of an orbit camera; the page computes the same."""
    a, e = math.radians(azimuth_deg), math.radians(elevation_deg)
    return (target[0] + distance * (math.sin(a) * math.cos(e)), target[1] + distance * (math.cos(a) * math.cos(e)),
            target[2] + distance * math.sin(e))


def _fixed(eye: Vec3, target: Vec3) -> CameraView:
    """A camera fixed at ``eye``; its orbit numbers (what the core reports) are those of the same place."""
    dx, dy, dz = (eye[k] - target[k] for k in range(3))
    distance = math.sqrt(dx * dx + dy * dy + dz * dz)
    return CameraView(azimuth_deg=round(math.degrees(math.atan2(dx, dy)), 2),
                      elevation_deg=round(math.degrees(math.asin(dz / distance)), 2),
                      distance=round(distance, 3), target=target, eye=eye)


PRESETS: dict[CameraPreset, CameraView] = {
    "front": CameraView(azimuth_deg=0.0, elevation_deg=18.0, distance=3.0),
    "side": CameraView(azimuth_deg=90.0, elevation_deg=12.0, distance=3.0),
    "top": CameraView(azimuth_deg=0.0, elevation_deg=85.0, distance=3.2),
    # from the drummer's eyes, looking at the kit
    "drummer": _fixed(eye=DRUMMER_EYES, target=(0.0, 0.55, 0.8)),
    # turns about the kit once every 30 s, starting from the front
    "orbit": CameraView(azimuth_deg=0.0, elevation_deg=20.0, distance=3.2, turn_deg_per_s=12.0),
}
"""Every preset but ``free`` (which uses the numbers it is sent)."""
DEFAULT_PRESET: CameraPreset = "front"
"""What a user who sets nothing sees: in the browser, in the video, in the core's and the Pd panel's numbers."""


def default_camera() -> dict[str, Any]:
    """The view's starting camera as the core keeps it and sends it to the page (a fresh, JSON-ready dict)."""
    return camera_for(DEFAULT_PRESET, 0.0, 0.0, 1.0, TARGET)


def camera_for(preset: CameraPreset, azimuth_deg: float, elevation_deg: float, distance: float,
               target: Vec3) -> dict[str, Any]:
    """The camera as the core keeps it (JSON-ready): ``free`` with the numbers given (degrees, metres), a named
    preset with its own numbers, which the page uses whatever a message carried besides the name."""
    if preset != "free":
        view = PRESETS[preset]
        azimuth_deg, elevation_deg, distance, target = view.azimuth_deg, view.elevation_deg, view.distance, view.target
    return {"preset": preset, "azimuth_deg": azimuth_deg, "elevation_deg": elevation_deg, "distance": distance,
            "target": list(target)}


def presets_json() -> dict[str, dict[str, Any]]:
    """The presets as the page reads them (``eye`` and ``turn_deg_per_s`` only where they apply)."""
    return {name: view.model_dump(mode="json", exclude_none=True)
            for name, view in PRESETS.items()}
