"""Graphics controls: the visual feedback parameters of the 3D view (2009 paper's middle panel).

Sent to the graphics node by the Pure Data panel, ``batteur send`` or any OSC
tool; the node applies them to every connected page. Plus the score position
shown in the view's status panel.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, ClassVar, Literal, Self

from pydantic import Field, model_validator
from pydantic_core import PydanticCustomError

from common.messages.base import DropReason, Family, MessageError, OscMessage, RigTime
from common.messages.registry import register

CameraPreset = Literal["free", "front", "side", "top", "drummer", "orbit"]
Layer = Literal["body", "sticks", "kit", "contacts", "trails", "plot", "status", "floor"]


@register
class GraphicsCamera(OscMessage):
    """Place the camera: a preset, or ``free`` with the orbit angles, distance and target given.

    Angles in degrees: azimuth 0 looks from the front of the kit (+y) towards
    the drummer, 90 from the drummer's right (+x); elevation above the horizon.
    A preset may be sent alone (``/batteur/graphics/camera top``): its own
    numbers apply, and numbers sent with it are not checked. ``free`` needs
    all six.
    """

    ADDRESS = "/batteur/graphics/camera"
    FAMILY = Family.CONTROL

    PRESET_NUMBERS: ClassVar[dict[str, float]] = {
        "azimuth_deg": 0.0, "elevation_deg": 18.0, "distance": 3.0, "target_x": 0.0, "target_y": 0.35,
        "target_z": 0.75}
    """What a preset's message carries for a number left out or out of range (the front preset's numbers; a
    preset uses its own whatever it carries), so it still fits the seven-argument wire form."""

    SHORT_FORM: ClassVar[str] = "PRESET alone (any preset but free)"

    preset: CameraPreset = Field(description="front, side, top, drummer (over the shoulder), orbit (turning), free")
    azimuth_deg: float = Field(ge=-360, le=360, description="orbit azimuth (free), degrees")
    elevation_deg: float = Field(ge=-89, le=89, description="orbit elevation (free), degrees")
    distance: float = Field(ge=0.3, le=20, description="camera distance from the target (free), metres")
    target_x: float = Field(ge=-10, le=10, description="look-at point x (free), metres")
    target_y: float = Field(ge=-10, le=10, description="look-at point y (free), metres")
    target_z: float = Field(ge=-10, le=10, description="look-at point z (free), metres")

    @classmethod
    def from_args(cls, args: Sequence[Any]) -> Self:
        """As :meth:`OscMessage.from_args`; a preset alone (one argument) takes :data:`PRESET_NUMBERS`, ``free``
        alone or any other count than 1 or 7 is ``wrong_arity`` saying what is needed."""
        numbers = " ".join(name.upper() for name in cls.PRESET_NUMBERS)
        if args and args[0] == "free" and len(args) != 7:
            raise MessageError(DropReason.WRONG_ARITY, f"free needs the 6 numbers after it: {numbers} (got "
                               f"{len(args) - 1})", cls.ADDRESS)
        if len(args) == 1:
            args = [args[0], *cls.PRESET_NUMBERS.values()]
        elif len(args) != 7:
            raise MessageError(DropReason.WRONG_ARITY, f"expected 7 arguments (PRESET {numbers}) or the preset "
                               f"alone (not free), got {len(args)}", cls.ADDRESS)
        return super().from_args(args)

    @model_validator(mode="before")
    @classmethod
    def _preset_ignores_numbers(cls, data: Any) -> Any:
        """A named preset's numbers are unused: one missing or out of range is replaced, not refused."""
        if not isinstance(data, dict) or data.get("preset") == "free":
            return data
        filled = dict(data)
        for name, default in cls.PRESET_NUMBERS.items():
            if not _within(cls, name, filled.get(name)):
                filled[name] = default
        return filled


@register
class GraphicsShow(OscMessage):
    """Show or hide one layer of the view."""

    ADDRESS = "/batteur/graphics/show"
    FAMILY = Family.CONTROL

    layer: Layer = Field(description="body, sticks, kit, contacts (impact markers), trails, plot, status, floor")
    visible: int = Field(ge=0, le=1, description="1 show, 0 hide")


@register
class GraphicsTrails(OscMessage):
    """Trails of the stick tips (and feet): how many seconds of path to draw (0: off)."""

    ADDRESS = "/batteur/graphics/trails"
    FAMILY = Family.CONTROL

    seconds: float = Field(ge=0, le=10, description="trail length, seconds (0 hides the trails)")


@register
class GraphicsPlot(OscMessage):
    """The live plot of stick-tip heights over time (2009 paper, Figure 5)."""

    ADDRESS = "/batteur/graphics/plot"
    FAMILY = Family.CONTROL

    window: float = Field(ge=0.5, le=30, description="time span shown, seconds")
    z_min: float = Field(ge=-1, le=3, description="lowest height shown, metres")
    z_max: float = Field(ge=-1, le=3, description="highest height shown, metres (above z_min)")

    @model_validator(mode="after")
    def _heights_in_order(self) -> Self:
        """An empty or upside-down height range would draw no plot at all."""
        if self.z_max <= self.z_min:
            raise PydanticCustomError("z_order", "z_max {z_max} must be above z_min {z_min} (metres)",
                                      {"z_max": f"{self.z_max:g}", "z_min": f"{self.z_min:g}"})
        return self


@register
class GraphicsLatency(OscMessage):
    """The latency window the picture is delayed by (the same as the sound's), seconds."""

    ADDRESS = "/batteur/graphics/latency"
    FAMILY = Family.CONTROL

    seconds: float = Field(ge=0, le=2, description="display delay, seconds")


@register
class GraphicsMode(OscMessage):
    """What the view shows: the live pose stream, or the loaded kinematic preview (keyframes, no physics)."""

    ADDRESS = "/batteur/graphics/mode"
    FAMILY = Family.CONTROL

    mode: Literal["live", "preview"] = Field(description="live: poses from physics; preview: loaded pose sequence")


@register
class GraphicsRejected(OscMessage):
    """Reply to a graphics control message that could not be applied (or decoded), and why."""

    ADDRESS = "/batteur/graphics/rejected"
    FAMILY = Family.CONTROL

    address: str = Field(max_length=128, description="address of the rejected message")
    reason: str = Field(max_length=512, description="why it was rejected")


@register
class ScorePosition(OscMessage):
    """Where the score being played is, for the view's status panel (sent by whoever plays the score)."""

    ADDRESS = "/batteur/graphics/score_position"
    FAMILY = Family.STATE

    time: RigTime = Field(description="rig time this position refers to, seconds")
    bar: int = Field(ge=0, description="bar number, from 0")
    beat: float = Field(ge=0, le=64, description="beat within the bar, from 0")
    tempo_bpm: float = Field(ge=0, le=1000, description="tempo, beats per minute")


def _within(model: type[OscMessage], name: str, value: Any) -> bool:
    """Whether ``value`` is a finite number inside the declared range of ``model``'s field ``name``."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        return False
    field = next(f for f in model.wire_fields() if f.name == name)
    return (field.minimum is None or value >= field.minimum) and (field.maximum is None or value <= field.maximum)
