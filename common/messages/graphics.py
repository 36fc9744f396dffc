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


PREVIEW_MIN_RATE, PREVIEW_MAX_RATE = 0.25, 2.0
"""The playback rates a preview accepts (``--preview-rate``, the page, :class:`GraphicsPreviewRate`): slower than a
quarter the strokes barely move, faster than twice the figure's 60 Hz poses skip most of a stroke."""


@register
class GraphicsPreviewRate(OscMessage):
    """Play the kinematic preview at this rate over its planned motion, from where it is (no jump).

    The page's *speed* select does the same. A node with no preview loaded refuses it
    (``/batteur/graphics/rejected``)."""

    ADDRESS = "/batteur/graphics/preview_rate"
    FAMILY = Family.CONTROL

    rate: float = Field(ge=PREVIEW_MIN_RATE, le=PREVIEW_MAX_RATE,
                        description="motion seconds per second: 1 as planned, 0.5 half speed (0.25 to 2)")


@register
class GraphicsPreviewBars(OscMessage):
    """Loop only bars FIRST to LAST of the previewed score (bars from 1, as the status panel counts them); ``0 0``:
    the whole score again.

    The motion goes on from where it is when that is inside the new range, else from the range's first bar. A node
    whose preview has no score (``--preview FILE.npz``) or no preview, or a range ending past the bar of the score's
    last note ("the score has 3 bars"), refuse it (``/batteur/graphics/rejected``)."""

    ADDRESS = "/batteur/graphics/preview_bars"
    FAMILY = Family.CONTROL

    first: int = Field(ge=0, le=100_000, description="first bar looped, from 1 (0 with last 0: the whole score)")
    last: int = Field(ge=0, le=100_000, description="last bar looped, from first on (0 with first 0: the whole score)")

    @model_validator(mode="after")
    def _a_range(self) -> Self:
        """A range that ends before it starts, or half of the whole-score ``0 0``, loops nothing."""
        if (self.first, self.last) != (0, 0) and not 1 <= self.first <= self.last:
            raise PydanticCustomError(
                "bar_range", "bars {first} to {last}: bars count from 1 and the range must not end before it starts "
                "(e.g. 3 4; 0 0: the whole score)", {"first": self.first, "last": self.last})
        return self

    @property
    def bars(self) -> tuple[int, int] | None:
        """(first, last), or None for the whole score."""
        return None if (self.first, self.last) == (0, 0) else (self.first, self.last)


@register
class GraphicsRejected(OscMessage):
    """Reply to a graphics control message that could not be applied (or decoded), and why; also to another
    service's control sent to a graphics node, naming the service that takes it."""

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
    # appended (7 Dec; a sender from before, a Pd patch, sends the four above): the view counted every meter in
    # quarter notes, a 12/8 bar 1 to 6.99 where a musician counts its 12 eighths
    beat_unit: float = Field(default=1.0, gt=0, le=4, description="the note the bar is counted in, quarter notes "
                             "(beat and tempo_bpm stay in quarter notes): its meter's 1/D note, 0.5 in x/8 (the view "
                             "counts a 12/8 bar in eighths, 1 to 12, as batteur compare does), 1 in x/4; a sender "
                             "without it (5 arguments): 1")

    APPENDED: ClassVar[tuple[str, ...]] = ("beat_unit",)
    """The fields appended after ``tempo_bpm``, oldest first: a position without them decodes with their defaults."""
    NEWER_ARGS: ClassVar[int] = 8
    """Arguments after the last known field a newer sender's position may carry (fields appended since): ignored."""


def _within(model: type[OscMessage], name: str, value: Any) -> bool:
    """Whether ``value`` is a finite number inside the declared range of ``model``'s field ``name``."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        return False
    field = next(f for f in model.wire_fields() if f.name == name)
    return (field.minimum is None or value >= field.minimum) and (field.maximum is None or value <= field.maximum)
