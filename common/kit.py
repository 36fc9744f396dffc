"""The drum kit: one description read by physics, interaction, sound and graphics.

Frame: metres, z up, the drummer sits at the origin facing +y, +x is the
drummer's right. Each kit object has a centre and a rotation (degrees, roll
pitch yaw, extrinsic x-y-z) that turns the object's local frame, whose +z is
the playing surface's outward normal, into the world frame.

Drum event types (Kragtwijk et al. 2001) map to an object, a hit point on it
(r/a, theta), a preferred limb, a minimum time gap and an elasticity.
"""

from __future__ import annotations

import enum
import functools
import json
import logging
import math
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal

import numpy as np
import yaml
from pydantic import AfterValidator, BaseModel, ConfigDict, Field, PrivateAttr, ValidationError, model_validator
from pydantic_core import PydanticCustomError

from common.datafile import BOUND_ERRORS, first_error, more_errors, parse_file
from common.input_file import NO_SUCH_FILE, file_problem
from common.output_paths import write_atomically

if TYPE_CHECKING:
    from common.score.limbs import LimbLengths

log = logging.getLogger(__name__)

KITS_DIR = Path(__file__).parent / "kits"
KIT_FILE = "a kit file (.yaml or .json)"
"""What :func:`load_kit` asks for when a path is not a regular file (``is a folder, not a kit file (...)``)."""


def kit_file(kit: str) -> Path:
    """The file a kit name or path stands for (:func:`load_kit`'s rule: a name without a suffix is a shipped kit in
    :data:`KITS_DIR`), resolved: a kit given as a name and as that file's path compare equal."""
    path = Path(kit).expanduser()
    return (KITS_DIR / f"{kit}.yaml" if not path.suffix else path).resolve()


class EventType(enum.StrEnum):
    """The 15 drum event types of Kragtwijk, Nijholt and Zwiers (2001)."""

    BASS = "BASS"
    SNARE = "SNARE"
    RIM = "RIM"
    HIGHTOM = "HIGHTOM"
    MIDTOM = "MIDTOM"
    FLOORTOM = "FLOORTOM"
    CRASH = "CRASH"
    RIDE = "RIDE"
    RIDEBELL = "RIDEBELL"
    SPLASH = "SPLASH"
    CHINA = "CHINA"
    HIHATOPEN = "HIHATOPEN"
    HIHATCLOSED = "HIHATCLOSED"
    HIHATPEDAL = "HIHATPEDAL"
    COWBELL = "COWBELL"


class Limb(enum.StrEnum):
    LEFT_HAND = "left_hand"
    RIGHT_HAND = "right_hand"
    LEFT_FOOT = "left_foot"
    RIGHT_FOOT = "right_foot"


ObjectKind = Literal["membrane", "cymbal", "hihat", "bell", "pedal", "throne", "stand"]
STRUCK_KINDS: frozenset[str] = frozenset({"membrane", "cymbal", "hihat", "bell"})
"""Object kinds a stick or a beater strikes: instruments (the others: a footboard is pressed; the throne and stands
are no instruments). A new kind of instrument goes here and in every layer that dispatches on ``kind``
(docs/contributing.md, "Adding a kit piece"; tests/test_object_kinds.py checks them)."""
Vec3 = tuple[float, float, float]
Unit = Annotated[float, Field(ge=0.0, le=1.0)]


FOOTBOARD_LENGTH_M = 0.26
"""Length of a pedal's footboard, heel hinge to toe, metres."""
PEDAL_REST_ANGLE_RAD = math.radians(22.0)
"""A footboard's angle above its floor plate at rest, radians (0: pressed flat)."""
FOOT_BALL_ALONG = 0.65
"""The ball of the foot presses a footboard this far along it from the heel (fraction of its length)."""


DEFAULT_SEAT_M: Vec3 = (0.0, 0.0, 0.52)
"""Where the drummer sits on a kit without a throne object, metres (the shipped kits' throne): the seat point of
the body (services/physics/drummer.py) and the origin of the planner's reach (common/score/limbs.py)."""


BEATER_REST_RAD = 0.9
"""A bass-drum beater's angle back from the head at rest (footboard up), radians; geared to the footboard (physics
builds it so, services/physics/kitbodies.py; the glTF export draws it so)."""
BEATER_CONTACT_PRESS = 0.95
"""How far the footboard is pressed (0 rest ... 1 flat) when the beater's ball meets the kick's head. Before it met
the head only with the board flat, which a foot pressing it steadily never reaches (it holds the board at about
0.986, ``FOOT_PRESS_TABLE``): soft kicks, which follow the board without overshooting the gear, stopped 3 mm short
of the head and did not sound (341 of 28,247 notes on 76 Groove validation files)."""
BEATER_BALL_RADIUS_M = 0.03
"""Radius of a bass-drum beater's ball, metres."""
BEATER_HIT_HEIGHT = 0.2
"""Where the beater's ball meets the kick's head: this fraction of the head's radius above its centre."""
STAND_ROD_RADIUS_M = 0.012
"""Radius of the rods standing under the mounted drums and cymbals, metres (drawn, not collided with)."""
HIHAT_CLOSED_GAP_M = 0.0016
"""Gap between a closed hi-hat's plates, metres: the physics' collision margins keep them this far apart when the
pedal clamps them together (services/physics/kitbodies.py); the top plate's surface is this plus its thickness
above the bottom plate's."""


def footboard_rise(press: float) -> float:
    """Height (metres) of a footboard pressed ``press`` (0 at rest ... 1 flat) above its flat position, at
    ``FOOT_BALL_ALONG`` of its length."""
    return FOOT_BALL_ALONG * FOOTBOARD_LENGTH_M * math.sin(PEDAL_REST_ANGLE_RAD * (1.0 - press))


FOOT_PRESS_TABLE: tuple[tuple[float, float], ...] = (
    (0.0, 0.986), (0.005, 0.971), (0.010, 0.937), (0.015, 0.901), (0.020, 0.863), (0.030, 0.774), (0.040, 0.665),
)
"""(foot target above the pedal's flat target, metres; how far the simulated foot holding it there presses the
footboard, 0 rest ... 1 flat), measured with services/physics (tests/physics/test_physics_groove.py checks it):
the shoe meets the tilted board nearer its hinge than the ball, so the board rises about 0.56 times as much as
the foot (and the sole sinks 1-2 mm into it)."""


CHICK_PRESS_MARGIN = 0.08
"""A hi-hat pedal stroke aims this much further down the pedal's travel than where the cymbals meet: a foot moving
at a metre per second leaves the footboard behind (its compliant contact, the board's inertia), so at the aimed
foot height the board reaches the closing point, not beyond (aimed at the closing point itself, the plates met
only after the foot had stopped, slowly or not at all)."""


def foot_target_for_press(press: float) -> float:
    """How far above a pedal's flat target (metres) a foot target must be for the foot to hold the footboard
    pressed ``press`` (``FOOT_PRESS_TABLE``, interpolated; clamped to the table's range)."""
    heights = [h for h, _ in FOOT_PRESS_TABLE][::-1]
    presses = [p for _, p in FOOT_PRESS_TABLE][::-1]
    if press <= presses[0]:
        return heights[0]
    for k in range(1, len(presses)):
        if press <= presses[k]:
            f = (press - presses[k - 1]) / (presses[k] - presses[k - 1])
            return heights[k - 1] + f * (heights[k] - heights[k - 1])
    return heights[-1]


MIRRORED_SUFFIX = "-mirrored"
"""Added to a kit's name by :meth:`Kit.mirrored` (and taken off again by mirroring back)."""
ANGLE_DECIMALS = 12
"""Decimals up to which a hit-point angle a kit file holds comes back exactly when mirrored twice."""
ANGLE_NOISE_RAD = 1e-14
"""How far (radians) ``pi - theta`` may be from an ``ANGLE_DECIMALS`` value for it to be that value: beyond one
float rounding of mirroring twice (< 2e-15 rad for angles within a few turns), short of the 2e-13 rad by which
``pi - theta`` of such a value misses every such value (pi's digits past the 12th decimal)."""


HIT_ANGLE_MIN_RAD = -math.pi
"""Least hit-point angle a kit holds (radians): with :data:`HIT_ANGLE_MAX_RAD`, the range ``pi - theta`` maps onto
itself (-pi <-> 2pi exactly in floats), holding an angle written -pi..pi or 0..2pi (mirroring turns one into the
other), within which every angle written with up to 12 decimals mirrors back exactly (:func:`mirrored_angle`)."""
HIT_ANGLE_MAX_RAD = 2 * math.pi
"""Greatest hit-point angle a kit holds (radians); see :data:`HIT_ANGLE_MIN_RAD`."""


def _within_hit_angles(theta: float) -> float:
    """``theta`` (radians) if a kit may hold it as a hit-point angle, else a validation error saying the range."""
    if not HIT_ANGLE_MIN_RAD <= theta <= HIT_ANGLE_MAX_RAD:  # NaN too
        raise PydanticCustomError(
            "hit_angle_range",
            "must be within -pi..2pi rad (-3.141593..6.283185: angles written -pi..pi or 0..2pi fit, and "
            "mirroring the kit keeps them within), got {theta}", {"theta": theta})
    return theta


HitAngle = Annotated[float, AfterValidator(_within_hit_angles)]
"""A hit-point angle in an object's frame, radians, -pi..2pi."""


def _zero_signless(value: float) -> float:
    """``value`` with a zero written 0.0, never -0.0 (negating or rounding a zero gives -0.0)."""
    return value + 0.0  # -0.0 + 0.0 is 0.0; any other value is unchanged


def mirrored_angle(theta: float) -> float:
    """A hit-point angle mirrored in the object's x (radians): ``pi - theta``, an involution on the angles kit
    files hold.

    ``pi - (pi - theta)`` can miss ``theta`` by one rounding (-1.5708 -> -1.5708000000000002): a result within
    :data:`ANGLE_NOISE_RAD` of a value with :data:`ANGLE_DECIMALS` decimals is that value. An angle written with
    up to 12 decimals mirrors to the float nearest ``pi - theta`` (as ``pi - theta`` always did), and that mirrors
    back to the written angle exactly. (No rule gives every float back: there are more floats near 0 than near pi.)
    The page's kit editor mirrors with the same rule (services/graphics/web/src/app.js ``mirroredAngle``). A zero
    is 0.0 (the page's JSON has no -0 either).
    """
    exact = math.pi - theta
    written = round(exact, ANGLE_DECIMALS)
    return _zero_signless(written) if abs(written - exact) <= ANGLE_NOISE_RAD else exact


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class KitObject(_Strict):
    """A physical object of the kit."""

    id: str = Field(pattern=r"^[a-z][a-z0-9_]*$", description="unique id, used in OSC messages")
    kind: ObjectKind
    position: Vec3 = Field(description="centre of the playing surface, metres (world)")
    rotation_deg: Vec3 = Field(default=(0.0, 0.0, 0.0), description="roll, pitch, yaw, degrees")
    radius: float = Field(gt=0, le=1.0, description="radius of the head or cymbal, metres")
    depth: float = Field(default=0.0, ge=0, le=1.0, description="shell depth or bell height, metres")
    thickness: float = Field(default=0.002, gt=0, le=0.1, description="cymbal or head thickness, metres")
    elasticity: Unit = Field(default=0.6, description="restitution of a stick strike, 0..1")
    bell_radius: float = Field(default=0.0, ge=0, description="cymbal bell radius, metres (0: none)")
    opening: Unit = Field(default=0.3, description="hi-hat opening at rest, 0 closed ... 1 open")
    closes_at: float = Field(default=0.85, gt=0.0, lt=1.0,
                             description="hi-hat: fraction of its pedal's travel at which the cymbals meet (the "
                                         "clutch); pressed further, the foot clamps them together")

    @property
    def bell_height(self) -> float:
        """How far a cymbal's bell top stands above its bow's playing surface, metres (0: no bell): the
        given ``depth``, else 0.4 x the bell radius, less the plate's thickness."""
        if self.bell_radius <= 0:
            return 0.0
        return max(self.depth, 0.4 * self.bell_radius) - self.thickness

    def surface_height(self, r_m: float) -> float:
        """Height of the playing surface above the object's plane ``r_m`` metres from its centre (the bell's
        top within the bell radius, else 0; for a hi-hat, the closed top plate's top), metres."""
        base = HIHAT_CLOSED_GAP_M + self.thickness if self.kind == "hihat" else 0.0
        return base + (self.bell_height if r_m < self.bell_radius else 0.0)

    def normal(self) -> Vec3:
        """World direction of the local +z axis (the playing surface's normal)."""
        r, p, y = (math.radians(a) for a in self.rotation_deg)
        # R = Rz(yaw) Ry(pitch) Rx(roll); third column
        nx = math.cos(y) * math.sin(p) * math.cos(r) + math.sin(y) * math.sin(r)
        ny = math.sin(y) * math.sin(p) * math.cos(r) - math.cos(y) * math.sin(r)
        nz = math.cos(p) * math.cos(r)
        return (nx, ny, nz)

    def rotation_matrix(self) -> tuple[Vec3, Vec3, Vec3]:
        """Rows of R = Rz(yaw) Ry(pitch) Rx(roll) (local -> world)."""
        r, p, y = (math.radians(a) for a in self.rotation_deg)
        cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
        return (
            (cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr),
            (sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr),
            (-sp, cp * sr, cp * cr),
        )

    def to_world(self, local: Vec3) -> Vec3:
        """A point in the object's local frame (metres) in world metres."""
        rows = self.rotation_matrix()
        x, y, z = (sum(row[k] * local[k] for k in range(3)) for row in rows)
        return (self.position[0] + x, self.position[1] + y, self.position[2] + z)


ZONES = frozenset({"centre", "edge", "bow", "rim", "rimshot", "bell", "open", "half", "closed", "pedal"})
"""Strike zones the sound service plays (an impact's ``zone``, a kit event's ``zone``): the interaction service's
(centre, edge, rim on a drum; bow, edge, bell on a cymbal), the shipped kits' events' (open, closed, pedal on the
hi-hat) and the demo's (rimshot, half). Any zone but rim/rimshot strikes a drum's head, any but bell a cymbal's
bow; an impact with another zone (a typo) is dropped and counted (the sound core's unknown_zone), not played as a
centre stroke, so a kit event with one is refused when the kit loads. Here, in common, so that the kit and the
sound service check against the same list."""


FOOT_EVENTS = frozenset({EventType.BASS, EventType.HIHATPEDAL})
"""Event types played by a foot on a footboard: a kit gives each a ``pedal`` (warned of without one:
:func:`layout_problems`; a kit for the sound service alone needs none)."""


class EventSpec(_Strict):
    """How one drum event type is played on this kit."""

    object: str = Field(description="id of the kit object struck")
    r: Annotated[float, Field(ge=0, le=1.2)] = Field(description="hit point radius, r/a")
    theta: HitAngle = Field(default=0.0, description="hit point angle in the object frame, radians, -pi..2pi")
    zone: str = Field(default="centre", description="zone name, one of ZONES: centre, edge, rim, bell, bow, ...")
    preferred: Limb = Field(description="limb that plays it by default")
    min_time_gap: float = Field(gt=0, le=2, description="shortest interval one limb can repeat it, seconds")
    pedal: str | None = Field(
        default=None,
        description="foot events: id of the pedal (footboard) object the foot presses; None for stick events",
    )
    rebound_min_time_gap: float | None = Field(
        default=None,
        gt=0,
        le=2,
        description="stick events: shortest interval of a rebound double (the second note a bounce played with the "
        "fingers), seconds; None: the kit's rebound_min_time_gap",
    )
    off_hand: tuple[Annotated[float, Field(ge=0, le=1.2)], HitAngle] | None = Field(
        default=None,
        description="stick events: the hit point (r/a, theta radians) when the other hand than ``preferred`` plays "
        "it, where that hand's stick reaches the surface tip first; None: the same point for both hands",
    )


class _Memo:
    """Work a frozen model keeps for itself: no part of its value (any two are equal, so kits compare by their
    fields as before; a pickled one comes back empty)."""

    def __init__(self) -> None:
        self.value: Any = None

    def __eq__(self, other: object) -> bool:
        return isinstance(other, _Memo)

    __hash__ = None  # type: ignore[assignment]

    def __reduce__(self) -> tuple[type[_Memo], tuple[()]]:
        return (_Memo, ())


PAIR_CROSS_LIMIT_M = 0.55
"""How far (x, metres, between the two hit points) a written pair preference may cross the arms before the geometry
overrides it (:meth:`Kit.stale_pairs`): beyond the crossings real conventions ask for (the shipped kits' crossed
hi-hat 0.21-0.23 m and crash over the backbeat 0.27 m; a crash moved left of the hi-hat 0.42 m, a hi-hat at x -0.58
0.39 m, both still played right-handed over the snare), short of a ride moved across the kit with ``RIDE,SNARE: 1``
kept (0.69-0.77 m). Until 7 Dec 0.38 m (the shoulders' width) overrode those conventions, a table the user wrote."""
PAIR_GEOMETRY_SPAN_M = 0.30
"""A geometric pair preference is the hit points' x distance over this, metres, at most 1 (docs/gestures.md)."""
PAIR_GEOMETRY_MIN_DX_M = 0.10
"""Hit points closer than this in x (metres) give no geometric pair preference."""


class Kit(_Strict):
    """A whole kit: objects, how each event type is played, pair-wise hand preferences."""

    name: str
    handedness: Literal["right", "left"] = "right"
    objects: list[KitObject]
    events: dict[EventType, EventSpec]
    pair_preference: dict[str, Annotated[float, Field(ge=-1, le=1)]] = Field(
        default_factory=dict,
        description="'A,B' -> pair(A, B) in [-1, 1]: -1 A left / B right, +1 A right / B left",
    )
    double_pedal: bool = False
    left_bass_pedal: str | None = Field(
        default=None,
        description="double pedal: id of the second footboard that drives the kick (BASS by the other foot than "
                    "BASS's preferred one: the left foot on a right-handed kit, the right on a mirrored one)",
    )
    note_objects: dict[int, str] = Field(
        default_factory=dict,
        description="MIDI pitch -> kit object id overriding the event's object (second ride, more toms)",
    )
    rebound_min_time_gap: float = Field(
        default=0.03,
        gt=0,
        le=2,
        description="shortest interval of a rebound double on one hand (a wrist stroke and its bounce on the same "
        "spot, the bounce played with the fingers) at soft to medium dynamics, seconds; see docs/gestures.md",
    )
    rebound_velocity_margin: float = Field(
        default=0.1,
        ge=0,
        le=1,
        description="a rebound double's second note may be at most this much louder than the first (velocity, 0..1)",
    )
    _pairs: _Memo = PrivateAttr(default_factory=lambda: _Memo())
    """:meth:`_pair_table`'s work and what it was worked out from."""

    @model_validator(mode="after")
    def _check_refs(self) -> Kit:
        ids = [o.id for o in self.objects]
        twice = sorted({i for i in ids if ids.count(i) > 1})
        if twice:  # named, with where: the designer's copied entry may be anywhere in a long list
            said = "; ".join(f"{i!r} is the id of " + " and ".join(f"objects.{k}" for k, o in enumerate(ids) if o == i)
                             for i in twice)
            raise ValueError(f"kit object ids must be unique: {said}")
        kinds = {o.id: o.kind for o in self.objects}
        for event, spec in self.events.items():
            if spec.object not in ids:
                raise ValueError(f"event {event.value} refers to unknown object {spec.object!r}")
            if spec.pedal is not None and spec.pedal not in ids:
                raise ValueError(f"event {event.value} refers to unknown pedal {spec.pedal!r}")
            if spec.pedal is not None and kinds[spec.pedal] != "pedal":  # physics builds a footboard only there
                raise ValueError(f"event {event.value}'s pedal {spec.pedal!r} is a {kinds[spec.pedal]}, not a pedal")
            if spec.zone not in ZONES:  # else every stroke of it is dropped by the sound service, silently
                raise ValueError(f"event {event.value}: no zone {spec.zone!r} (zones: {', '.join(sorted(ZONES))})")
        for pitch, obj in self.note_objects.items():
            if obj not in ids:
                raise ValueError(f"note_objects[{pitch}] refers to unknown object {obj!r}")
            if not 0 <= pitch <= 127:
                raise ValueError(f"note_objects key {pitch} is not a MIDI pitch (0..127)")
        if self.left_bass_pedal is not None and self.left_bass_pedal not in ids:
            raise ValueError(f"left_bass_pedal refers to unknown object {self.left_bass_pedal!r}")
        if self.left_bass_pedal is not None and kinds[self.left_bass_pedal] != "pedal":
            raise ValueError(f"left_bass_pedal {self.left_bass_pedal!r} is a {kinds[self.left_bass_pedal]}, "
                             "not a pedal")
        if self.double_pedal and self.left_bass_pedal is None:
            raise ValueError("double_pedal needs left_bass_pedal (the left footboard object id)")
        for key in self.pair_preference:
            parts = key.split(",")
            if len(parts) != 2 or any(p not in EventType.__members__ for p in parts):
                raise ValueError(f"pair_preference key {key!r} must be 'EVENT,EVENT'")
        return self

    def object(self, object_id: str) -> KitObject:
        for o in self.objects:
            if o.id == object_id:
                return o
        raise KeyError(f"kit {self.name!r} has no object {object_id!r}")

    def kick(self) -> KitObject | None:
        """The bass drum: the object BASS strikes, whatever its id (None: the kit plays no BASS)."""
        return self.object(self.events[EventType.BASS].object) if EventType.BASS in self.events else None

    def kick_pedal(self) -> str | None:
        """Id of the footboard whose beater strikes the kick: BASS's ``pedal`` (None: the kit plays no BASS). A
        double pedal's second footboard is ``left_bass_pedal``."""
        return self.events[EventType.BASS].pedal if EventType.BASS in self.events else None

    def hihat_pedal(self) -> str | None:
        """Id of the footboard that closes the hi-hat: HIHATPEDAL's ``pedal`` (None: the kit plays no HIHATPEDAL)."""
        return self.events[EventType.HIHATPEDAL].pedal if EventType.HIHATPEDAL in self.events else None

    def spec(self, event: EventType) -> EventSpec:
        """How ``event`` is played; ``KeyError`` naming the kit when it has no such event."""
        try:
            return self.events[event]
        except KeyError:
            raise KeyError(f"kit {self.name!r} does not play {event.value}") from None

    def seat_position(self) -> Vec3:
        """Where the drummer sits, metres: the throne object's position, else :data:`DEFAULT_SEAT_M`."""
        throne = next((o for o in self.objects if o.kind == "throne"), None)
        return DEFAULT_SEAT_M if throne is None else throne.position

    def object_for(self, event: EventType, pitch: int | None = None) -> KitObject:
        """The object struck for ``event`` (a pitch in ``note_objects`` overrides it)."""
        if pitch is not None and pitch in self.note_objects:
            return self.object(self.note_objects[pitch])
        return self.object(self.spec(event).object)

    def hit_point(self, event: EventType, pitch: int | None = None) -> tuple[Vec3, Vec3]:
        """World hit point (metres) and outward surface normal (unit) of ``event``.

        The hit point is ``(r * radius * cos theta, r * radius * sin theta, h)`` in
        the object's local frame, rotated and translated into the world, with ``h`` the
        surface's height there (a cymbal's bell top stands above its bow).
        """
        spec = self.spec(event)
        return self._point_on(self.object_for(event, pitch), spec.r, spec.theta)

    @staticmethod
    def _point_on(obj: KitObject, r: float, theta: float) -> tuple[Vec3, Vec3]:
        r_m = r * obj.radius
        local = (r_m * math.cos(theta), r_m * math.sin(theta), obj.surface_height(r_m))
        return obj.to_world(local), obj.normal()

    def struck_point(self, event: EventType, limb: Limb) -> tuple[float, float]:
        """(r as a fraction of the radius, theta radians) of the point ``limb`` strikes for ``event``: the event's
        ``off_hand`` point when a hand other than the preferred one plays it, else its own."""
        spec = self.spec(event)
        if spec.pedal is None and spec.off_hand is not None and limb != spec.preferred:
            return spec.off_hand
        return spec.r, spec.theta

    def effector_target(self, event: EventType, limb: Limb, pitch: int | None = None) -> tuple[Vec3, Vec3]:
        """Where the limb's tracked point is at contact (metres) and the approach normal.

        Stick events: the hit point (``off_hand``'s when the other hand plays it). Foot events: the footboard
        (pedal object centre, the footboard pressed flat; the left bass pedal when the left foot plays BASS), normal +z;
        for the hi-hat pedal, the foot height at which the footboard reaches the point where the cymbals meet
        (``closes_at`` of the hi-hat, plus ``CHICK_PRESS_MARGIN`` for the board's lag), which a stroke passes
        at speed on its way down (the chick).
        """
        spec = self.spec(event)
        if spec.pedal is None:
            return self._point_on(self.object_for(event, pitch), *self.struck_point(event, limb))
        x, y, z = self.object(self.pedal_for(event, limb)).position
        if event == EventType.HIHATPEDAL:
            z += foot_target_for_press(min(self.hihat_closes_at() + CHICK_PRESS_MARGIN, 1.0))
        return (x, y, z), (0.0, 0.0, 1.0)

    def pedal_for(self, event: EventType, limb: Limb) -> str:
        """The footboard object ``limb`` presses for the foot event ``event``: the event's pedal, or the left bass
        pedal when the other foot than BASS's preferred one plays it. Raises ``ValueError`` for a stick event."""
        spec = self.spec(event)
        if spec.pedal is None:
            raise ValueError(f"{event.value} is struck with a stick, not a pedal")
        if event == EventType.BASS and self.left_bass_pedal is not None and limb != spec.preferred:
            return self.left_bass_pedal
        return spec.pedal

    def hihat_closes_at(self) -> float:
        """The hi-hat's ``closes_at`` (its pedal travel at which the cymbals meet); the default without a hi-hat."""
        hihat = next((o for o in self.objects if o.kind == "hihat"), None)
        return hihat.closes_at if hihat is not None else float(KitObject.model_fields["closes_at"].default)

    def pair(self, a: EventType, b: EventType) -> float:
        """pair(a, b) in [-1, 1]; antisymmetric, 0 when unspecified. A written preference that would cross the arms
        further than :data:`PAIR_CROSS_LIMIT_M` as the objects stand gives way to the geometry's
        (:meth:`stale_pairs`)."""
        table = self._pair_table()
        if (a, b) in table:
            return table[(a, b)]
        if (b, a) in table:
            return -table[(b, a)]
        return 0.0

    def geometry_pair(self, a: EventType, b: EventType) -> float:
        """The preference the geometry gives (docs/gestures.md, the shipped kits' generated entries): the event
        whose hit point is further to the drummer's right to the right hand, min(1, dx / 0.30 m) rounded to 0.01,
        when the hit points are more than 10 cm apart in x on different objects; else 0."""
        if self.spec(a).object == self.spec(b).object:
            return 0.0
        dx = self.hit_point(a)[0][0] - self.hit_point(b)[0][0]
        if abs(dx) <= PAIR_GEOMETRY_MIN_DX_M:
            return 0.0
        return _zero_signless(round(max(-1.0, min(1.0, dx / PAIR_GEOMETRY_SPAN_M)), 2))

    def stale_pairs(self) -> dict[str, tuple[float, float]]:
        """Written ``pair_preference`` entries the geometry overrides: key -> (written, used). An entry is stale
        when, as the objects stand, the hand it gives each event would cross the arms further (x, metres, between
        the hit points) than :data:`PAIR_CROSS_LIMIT_M`: the conventions kits write (a crossed hi-hat, the right
        hand on the crash over the backbeat, even with the crash left of the hi-hat) cross up to 0.42 m; a ride
        moved far to the left with ``RIDE,SNARE: 1`` kept would put the right hand 0.7 m across the left."""
        return {f"{a.value},{b.value}": (written, used) for (a, b), (written, used) in self._pair_table(True).items()
                if used != written}

    def _pair_table(self, both: bool = False) -> dict[tuple[EventType, EventType], Any]:
        """(a, b) -> the pair preference used (``both``: (written, used)), worked out once per kit: the kit is frozen,
        and a copy with other objects or events (``model_copy(update=...)``) holds other containers, so it is
        worked out again for it."""
        basis = (self.objects, self.events, self.pair_preference)
        cached = self._pairs.value
        if cached is None or any(x is not y for x, y in zip(cached[0], basis, strict=True)):
            table: dict[tuple[EventType, EventType], tuple[float, float]] = {}
            for key, written in self.pair_preference.items():
                a, b = (EventType(part) for part in key.split(","))
                used = written
                if written != 0.0 and a in self.events and b in self.events:
                    right, left = (a, b) if written > 0 else (b, a)  # the hands the entry gives them
                    if self.hit_point(left)[0][0] - self.hit_point(right)[0][0] > PAIR_CROSS_LIMIT_M:
                        used = self.geometry_pair(a, b)
                table[(a, b)] = (written, used)
            cached = self._pairs.value = (basis, table)
        table = cached[1]
        return dict(table) if both else {k: used for k, (_, used) in table.items()}

    def mirrored(self) -> Kit:
        """The left-handed setup: x mirrored, hands and feet swapped; mirroring it again gives this kit back (the
        name's ``-mirrored`` suffix toggles as ``handedness`` does, hit-point angles by :func:`mirrored_angle`).
        A zero it negates is 0.0, not -0.0 (a kit file shows no ``-0.0``)."""
        swap = {
            Limb.LEFT_HAND: Limb.RIGHT_HAND,
            Limb.RIGHT_HAND: Limb.LEFT_HAND,
            Limb.LEFT_FOOT: Limb.RIGHT_FOOT,
            Limb.RIGHT_FOOT: Limb.LEFT_FOOT,
        }
        objects = [
            o.model_copy(
                update={
                    "position": (_zero_signless(-o.position[0]), o.position[1], o.position[2]),
                    "rotation_deg": (o.rotation_deg[0], _zero_signless(-o.rotation_deg[1]),
                                     _zero_signless(-o.rotation_deg[2])),
                }
            )
            for o in self.objects
        ]
        events = {
            e: s.model_copy(update={"preferred": swap[s.preferred], "theta": mirrored_angle(s.theta),
                                    "off_hand": None if s.off_hand is None else (s.off_hand[0],
                                                                                 mirrored_angle(s.off_hand[1]))})
            for e, s in self.events.items()
        }
        pairs = {k: _zero_signless(-v) for k, v in self.pair_preference.items()}
        return Kit(
            name=self.name.removesuffix(MIRRORED_SUFFIX) if self.name.endswith(MIRRORED_SUFFIX)
            else self.name + MIRRORED_SUFFIX,
            handedness="left" if self.handedness == "right" else "right",
            objects=objects,
            events=events,
            pair_preference=pairs,
            double_pedal=self.double_pedal,
            left_bass_pedal=self.left_bass_pedal,
            note_objects=dict(self.note_objects),
            rebound_min_time_gap=self.rebound_min_time_gap,
            rebound_velocity_margin=self.rebound_velocity_margin,
        )


def load_kit(source: str | Path = "default", height_m: float | None = None, warn: bool = True,
             lengths: LimbLengths | None = None) -> Kit:
    """Load a kit by shipped name (``default``) or from a YAML/JSON file path.

    Raises ``FileNotFoundError`` for an unknown name or path, or a path that is not a regular file (a folder, a
    device, a pipe: :func:`common.input_file.file_problem`'s words), and ``ValueError`` naming the file for one that is
    not UTF-8 text, not valid YAML/JSON (line and column) or not a valid kit (the first problem, on one line).
    A valid kit holding instruments the drummer cannot play (out of reach, struck by no event) loads with one
    logged warning per instrument (:func:`common.score.limbs.unplayable_instruments`), the reach that of a drummer
    ``height_m`` tall (metres; None: the default 1.75 m drummer), whom a warning then names; with ``lengths``, a
    skeleton's arms and legs (``--skeleton-bvh``), the reach is theirs and a warning says so. ``warn=False``: no
    such warnings (a kit read again for a render that already warned of it).
    """
    path = Path(source)
    shipped = sorted(p.stem for p in KITS_DIR.glob("*.yaml"))
    if not path.suffix:
        if str(source) not in shipped and path.exists():  # a name is a shipped kit: a file by that name is none
            raise FileNotFoundError(f"{str(source)!r} is a {_kind(path)}, not a kit: give a kit file ending in .yaml "
                                    f"or .json, or a shipped kit ({', '.join(shipped)})")
        path = KITS_DIR / f"{source}.yaml"
    problem = file_problem(path, KIT_FILE)
    if problem == NO_SUCH_FILE:
        raise FileNotFoundError(f"no kit file {str(source)!r} (shipped kits: {', '.join(shipped)})")
    if problem is not None:  # a folder, a device, a pipe: never opened (a pipe would wait for a writer for ever)
        raise FileNotFoundError(f"{path}: {problem}")
    try:
        data = parse_file(path)
    except ValueError as exc:
        binary = _binary_kind(path)
        if binary is not None:  # a score or a recording given as the kit: "not UTF-8 text (...)" said nothing
            raise ValueError(f"{str(path)!r} is {binary}, not a kit: give a kit file ending in .yaml or .json, or "
                             f"a shipped kit ({', '.join(shipped)})") from None
        raise ValueError(f"kit file {str(path)!r} is {exc}") from None
    try:
        kit = Kit.model_validate(data)
    except ValidationError as exc:
        others = more_errors(exc)
        more = f" (and {others} more)" if others else ""
        raise ValueError(f"kit file {str(path)!r} is not a valid kit: {kit_problem(exc, data)}{more}") from None
    if not warn:
        return kit
    from common.score.limbs import STATURE_M, unplayable_instruments  # here: limbs imports this module

    problems = layout_problems(kit) + unplayable_instruments(kit, STATURE_M if height_m is None else height_m,
                                                               lengths)
    for problem in problems:  # a valid kit may still hold objects the drummer cannot play
        log.warning("kit file %r: %s", str(path), problem)
    return kit


SOLID_KINDS = frozenset({"membrane", "cymbal", "hihat", "bell"})
"""Object kinds :func:`layout_problems` takes as solids (drums as cylinders, cymbals as plates)."""
SEATED_HEAD_M = 0.9
"""How far above the seat a seated 1.75 m drummer's head reaches, metres (about half the stature, less the legs'
share under the seat): an object's centre over the seat, up to here, is inside the drummer."""
PLATE_HALF_M = 0.01
"""Half the slab a cymbal or hi-hat is taken as for the overlap check, metres (its plate with the clearance a swing
needs)."""
OVERLAP_MARGIN_M = 0.01
"""How far inside another object (metres, from its surface) a point must be to be an overlap: objects that only
touch (rack toms rim to rim) are not warned of."""


FACES_FLOOR_NZ = -0.5
"""A stick-struck object whose surface normal points further down than this (tilted more than 120 degrees from
level) faces the floor (:func:`layout_problems`); a gong hung nearly upright (95 degrees, -0.09) does not."""


def layout_problems(kit: Kit) -> list[str]:
    """Where the kit's objects stand as no kit can, one line each naming the objects and what is wrong (for a
    warning as the kit loads, with :func:`common.score.limbs.unplayable_instruments`): an object whose centre is
    in the throne or the drummer seated on it (over the seat, up to :data:`SEATED_HEAD_M` above it), a drum or
    cymbal inside another (a point of one's (:func:`_solid_points`) deeper than :data:`OVERLAP_MARGIN_M` in the
    other: drums as cylinders from their head down their depth, cymbals and the hi-hat as plates), a stick-struck
    object whose playing surface faces the floor (rolled upside down), an object below the floor, and
    ``pair_preference`` entries the geometry overrides (:meth:`Kit.stale_pairs`); and a foot event (BASS,
    HIHATPEDAL) without a ``pedal``. The shipped kits give none."""
    lines: list[str] = []
    seat = np.asarray(kit.seat_position())
    throne = next((o for o in kit.objects if o.kind == "throne"), None)
    seat_radius = throne.radius if throne is not None else 0.18
    kick = kit.kick()
    for event in sorted(FOOT_EVENTS & set(kit.events)):
        spec = kit.events[event]
        if spec.pedal is None:  # physics builds no beater (no rod) for it: its notes would never sound
            lines.append(f"events.{event.value} has no pedal: nothing a foot presses "
                         f"{'drives a beater into' if event == EventType.BASS else 'closes'} {spec.object!r}, so "
                         "its notes do not sound when played (pedal: the id of a footboard object, kind pedal)")
    for obj in kit.objects:
        centre = np.asarray(obj.position)
        if obj.kind != "throne" and math.hypot(*(centre[:2] - seat[:2])) < seat_radius \
                and centre[2] < seat[2] + SEATED_HEAD_M:
            lines.append(f"{obj.id}: its centre {_shown_point(obj.position)} is in the throne, where the drummer "
                         f"sits (within {seat_radius:g} m of the seat at {_shown_point(tuple(seat))} and below the "
                         "seated drummer's head)")
        if centre[2] < 0.0:
            lines.append(f"{obj.id}: its centre {_shown_point(obj.position)} is {-centre[2]:.3g} m below the floor "
                         "(z is height above the floor, metres)")
        normal = obj.normal()
        if obj.kind in SOLID_KINDS and obj is not kick and normal[2] < FACES_FLOOR_NZ:
            lines.append(f"{obj.id}: its playing surface faces the floor (rotation_deg {_shown_point(obj.rotation_deg)}"
                         f", surface normal {_shown_point(normal, 2)}): a stick strikes it from above or the side; a "
                         "roll or pitch beyond 120 degrees turns it toward the floor")
    stale = kit.stale_pairs()
    if stale:  # the file's table was written for another layout (a kit copied and its objects moved)
        shown = ", ".join(f"{key} {written:g} -> {used:g}" for key, (written, used) in list(stale.items())[:6])
        lines.append(f"pair_preference: {len(stale)} entr{'y' if len(stale) == 1 else 'ies'} would cross the arms "
                     f"more than {PAIR_CROSS_LIMIT_M:g} m as the objects stand, so the geometry's preference is used "
                     f"({shown}{', ...' if len(stale) > 6 else ''}): moved objects leave the table stale; write it "
                     "again from this layout (docs/gestures.md, 'Pair table')")
    solids = [o for o in kit.objects if o.kind in SOLID_KINDS]
    for k, a in enumerate(solids):
        for b in solids[k + 1:]:
            if _inside(_solid_points(a), b) or _inside(_solid_points(b), a):
                lines.append(f"{a.id} and {b.id} overlap: one stands inside the other ({a.id} at "
                             f"{_shown_point(a.position)}, radius {a.radius:g} m; {b.id} at "
                             f"{_shown_point(b.position)}, radius {b.radius:g} m)")
    return lines


def _shown_point(point: tuple[float, ...], decimals: int = 3) -> str:
    """``(0, 0, 0.55)``: a point or vector for a message, without float noise."""
    return "(" + ", ".join(f"{round(v, decimals) + 0.0:g}" for v in point) + ")"


def _solid_points(obj: KitObject) -> np.ndarray:
    """Points that stand for ``obj``'s solid (world metres, (n, 3)): a drum's axis from its head's centre down to its
    depth (its rim may overhang another's, as a rack tom's over the snare), a plate's centre and a ring at 0.9 of its
    radius (two cymbals' plates crossing would clash)."""
    centre = np.asarray(obj.position)
    n = np.asarray(obj.normal())
    if obj.kind in ("membrane", "bell"):
        return np.array([centre - d * obj.depth * n for d in (0.0, 0.25, 0.5, 0.75, 1.0)])
    rows = np.asarray(obj.rotation_matrix())
    ex, ey = rows[:, 0], rows[:, 1]
    ring = [0.9 * obj.radius * (math.cos(a) * ex + math.sin(a) * ey) for a in np.linspace(0, 2 * math.pi, 12,
                                                                                          endpoint=False)]
    return np.array([centre, *(centre + r for r in ring)])


def _inside(points: np.ndarray, obj: KitObject) -> bool:
    """Whether any of ``points`` (world metres, (n, 3)) is more than :data:`OVERLAP_MARGIN_M` inside ``obj``'s solid:
    a drum's cylinder from its head down its depth, a plate's slab :data:`PLATE_HALF_M` each side."""
    n = np.asarray(obj.normal())
    rel = points - np.asarray(obj.position)
    along = rel @ n
    radial = np.linalg.norm(rel - np.outer(along, n), axis=1)
    if obj.kind in ("membrane", "bell"):
        low, high = -obj.depth + OVERLAP_MARGIN_M, -OVERLAP_MARGIN_M
    else:
        low, high = -PLATE_HALF_M, PLATE_HALF_M
    return bool(np.any((along > low) & (along < high) & (radial < obj.radius - OVERLAP_MARGIN_M)))


def kit_problem(exc: ValidationError, data: Any = None) -> str:
    """The first problem of a kit file, in plain words: a kit check's own message without pydantic's
    ``Value error, ``, a number out of bounds as its field, its value and the range the field takes
    (``events.SNARE.min_time_gap: 5 is out of range: more than 0, at most 2``), an event type the kit may not
    name with the ones it may, else :func:`first_error`'s. With the file's ``data``, an object's entry is named by
    its id too (``objects.8 (ride).radius: ...``: an index alone left the designer counting)."""
    first = exc.errors()[0]
    loc = tuple(first.get("loc", ()))
    said = _named_object(first_error(exc), loc, data)  # a kit check's own message as it is (datafile.error_message)
    if first.get("type") == "enum" and len(loc) == 3 and loc[0] == "events" and loc[2] == "[key]":
        return (f"events.{loc[1]}: {str(loc[1])!r} is not an event type (the event types are "
                f"{', '.join(e.value for e in EventType)})")
    value = first.get("input")
    if first.get("type") not in BOUND_ERRORS or isinstance(value, bool) or not isinstance(value, (int, float)) \
            or math.isnan(value):  # a NaN: first_error's "must be a finite number"
        return said
    bounds = _bounds_in_words(_kit_schema_at(loc))
    if not bounds:
        return said
    return _named_object(f"{'.'.join(str(p) for p in loc)}: {value:g} is out of range: {bounds}", loc, data)


def _named_object(said: str, loc: tuple[int | str, ...], data: Any) -> str:
    """``said`` with its leading ``objects.N`` followed by the object's id in ``data`` (``objects.8 (ride)``) when
    the problem is in that object and the file gives it an id; else as it is."""
    if len(loc) < 2 or loc[0] != "objects" or not isinstance(loc[1], int) or not isinstance(data, dict):
        return said
    objects = data.get("objects")
    if not isinstance(objects, list) or not 0 <= loc[1] < len(objects) or not isinstance(objects[loc[1]], dict):
        return said
    object_id = objects[loc[1]].get("id")
    where = f"objects.{loc[1]}"
    if not isinstance(object_id, str) or not object_id or not said.startswith(where) \
            or said[len(where):len(where) + 1] not in (".", ":"):
        return said
    return f"{where} ({object_id}){said[len(where):]}"


@functools.cache
def _kit_schema() -> dict[str, Any]:
    """The kit's JSON schema: where each field's bounds are written once, whatever the nesting."""
    return Kit.model_json_schema()


def _kit_schema_at(loc: tuple[int | str, ...]) -> dict[str, Any]:
    """The schema of the value at ``loc`` (pydantic's error location) in a kit; {} when it cannot be followed."""
    schema = _kit_schema()
    node = _resolved(schema, schema)
    for key in loc:
        if isinstance(key, int) and "prefixItems" in node and key < len(node["prefixItems"]):
            node = node["prefixItems"][key]
        elif isinstance(key, int) and isinstance(node.get("items"), dict):
            node = node["items"]
        elif isinstance(key, str) and key in node.get("properties", {}):
            node = node["properties"][key]
        elif isinstance(node.get("additionalProperties"), dict):  # a mapping's value (events.SNARE)
            node = node["additionalProperties"]
        else:
            return {}
        node = _resolved(node, schema)
    return node


def _resolved(node: dict[str, Any], schema: dict[str, Any]) -> dict[str, Any]:
    """``node`` with its ``$ref`` followed and an optional value's non-null choice taken."""
    for _ in range(8):  # references chain at most a few deep
        if "$ref" in node:
            node = schema.get("$defs", {}).get(node["$ref"].rsplit("/", 1)[-1], {})
        elif "anyOf" in node:
            choices = [c for c in node["anyOf"] if c.get("type") != "null"]
            node = choices[0] if len(choices) == 1 else node
            if len(choices) != 1:
                break
        else:
            break
    return node


def _bounds_in_words(node: dict[str, Any]) -> str:
    """``more than 0, at most 2`` from a schema's bounds ('' without any)."""
    words = [f"{word} {node[key]:g}" for key, word in (("exclusiveMinimum", "more than"), ("minimum", "at least"),
                                                       ("exclusiveMaximum", "less than"), ("maximum", "at most"))
             if isinstance(node.get(key), (int, float))]
    return ", ".join(words)


def _binary_kind(path: Path) -> str | None:
    """``a MIDI file`` or ``an audio file (WAV)`` when the first bytes of ``path`` are one's, else None."""
    from common.score.events import audio_kind, starts_as_midi  # here: events imports this module

    try:
        with path.open("rb") as f:
            head = f.read(12)
    except OSError:
        return None
    if starts_as_midi(head):
        return "a MIDI file"
    kind = audio_kind(head)  # never for UTF-16/32 text, whose mark FF FE is also an MPEG frame's sync
    return None if kind is None else f"an audio file ({kind})"


def _kind(path: Path) -> str:
    """What ``path`` is, for a message: a file, a folder or another thing (a device, a pipe)."""
    return "file" if path.is_file() else "folder" if path.is_dir() else "path"


def save_kit(kit: Kit, path: Path) -> None:
    """Write a kit as YAML (or JSON when the path ends in .json), whole or not at all (a crash or a full disk
    leaves the earlier file)."""
    data = kit.model_dump(mode="json")
    text = json.dumps(data, indent=2) if path.suffix == ".json" else yaml.safe_dump(data, sort_keys=False)
    write_atomically(path, text.encode("utf-8"))


def stand_rods(objects: list[KitObject], kick: str | None = None) -> list[tuple[np.ndarray, float]]:
    """(top (3,), height) of each stand rod, world metres: under each mounted drum and cymbal of ``objects``, up to
    the underside of its centre (physics' stand bodies and the glTF export's rods). The kick (``kick``: its id,
    :meth:`Kit.kick`) and a drum whose shell reaches the floor (:func:`shell_on_floor`) stand on their shells: no
    rod. Until 7 Dec every drum tilted past 60 degrees lost its rod: toms tilted steeply floated in the air."""
    rods = []
    for obj in objects:
        if obj.kind in ("pedal", "throne") or (obj.kind == "membrane" and (obj.id == kick or shell_on_floor(obj))):
            continue
        n = np.asarray(obj.normal())
        # the stand reaches the underside of the object's centre
        top = np.asarray(obj.position) - n * (max(obj.depth, 0.01) if obj.kind == "membrane" else 0.02)
        height = float(top[2])
        if height > 0.05:
            rods.append((top, height))
    return rods


SHELL_ON_FLOOR_M = 0.05
"""A drum whose shell comes this close to the floor (metres) stands on it, as a kick does (:func:`stand_rods`)."""


def shell_on_floor(obj: KitObject) -> bool:
    """Whether the drum ``obj``'s shell (a cylinder of its radius from the head's centre down its depth) comes
    within :data:`SHELL_ON_FLOOR_M` of the floor: its lowest point is a rim's, the head's or the shell's far end."""
    nz = float(obj.normal()[2])
    centre_z = float(obj.position[2])
    lowest = min(centre_z, centre_z - obj.depth * nz) - obj.radius * math.sqrt(max(0.0, 1.0 - nz * nz))
    return lowest <= SHELL_ON_FLOOR_M


BEATER_AXLE_TO_HEAD_M = 0.12
"""How far in front of the kick's head (toward the drummer) a beater's axle sits, metres."""
BEATER_AXLE_HEIGHT_M = 0.10
"""A beater's axle above its pedal's origin, metres (as physics builds it)."""
BEATER_ROD_RADIUS_M = 0.004
"""A beater rod's radius, metres (as physics draws it)."""
DOUBLE_PEDAL_BEATER_GAP_M = 0.07
"""A double pedal's second beater sits this far beside the main one along x, metres (as physics builds it)."""


class StandRod(_Strict):
    """A stand rod: vertical, from the floor up to ``top``."""

    top: Vec3 = Field(description="the rod's top, world metres (under the centre of the object it holds)")
    height: float = Field(description="the rod's length from the floor, metres (the top's z)")
    radius: float = Field(description="metres")


class Beater(_Strict):
    """A bass-drum beater as physics builds it: a rod from its axle to a ball, turning about the world x axis,
    geared to its pedal's footboard."""

    pedal: str = Field(description="id of the footboard that drives it")
    axle: Vec3 = Field(description="the axle's centre, world metres")
    axle_from_pedal: Vec3 = Field(description="the axle's centre from its pedal's origin, metres (pedal frame, "
                                              "axes as the world's: where physics joins it to the pedal)")
    lean_rad: float = Field(description="the rod's angle from vertical toward the kick (+y) at beater angle 0, "
                                        "where its ball is pressed into the head, radians")
    rest_rad: float = Field(description="the beater's angle back from there toward the drummer with the footboard "
                                        "up, radians; with the footboard pressed p (0 rest ... 1 flat): "
                                        "rest_rad x (1 - p)")
    rod_length: float = Field(description="from the axle to the ball's centre, metres")
    rod_radius: float = Field(description="metres")
    ball_radius: float = Field(description="metres")


class KitHardware(_Strict):
    """The hardware physics builds around a kit's objects (drawn by the live view and the glTF export alike)."""

    beaters: list[Beater]
    stands: list[StandRod]


def _beater(kit: Kit, pedal: KitObject, kick: KitObject) -> Beater:
    """``pedal``'s beater, computed in the pedal's frame (physics joins it there: services/physics/kitbodies.py
    ``_pedal_robot``), then placed."""
    dx = 0.0
    main = kit.kick_pedal()
    if pedal.id != main:  # a double pedal's second beater sits beside the main one (a cardan shaft)
        main_x = next((o.position[0] for o in kit.objects if o.id == main), pedal.position[0])
        side = 1.0 if pedal.position[0] < main_x else -1.0
        dx = (main_x - side * DOUBLE_PEDAL_BEATER_GAP_M) - pedal.position[0]
    axle_y = kick.position[1] - pedal.position[1] - BEATER_AXLE_TO_HEAD_M
    hit_z = kick.position[2] - pedal.position[2] + BEATER_HIT_HEIGHT * kick.radius
    rise = hit_z - BEATER_AXLE_HEIGHT_M
    # at beater angle 0 the ball is pressed this far into the head, so that it meets it at BEATER_CONTACT_PRESS
    depth = (1.0 - BEATER_CONTACT_PRESS) * BEATER_REST_RAD * math.hypot(BEATER_AXLE_TO_HEAD_M, rise)
    reach = BEATER_AXLE_TO_HEAD_M - BEATER_BALL_RADIUS_M + depth  # axle to the ball's centre, along y
    x, y, z = pedal.position
    return Beater(pedal=pedal.id, axle=(x + dx, y + axle_y, z + BEATER_AXLE_HEIGHT_M),
                  axle_from_pedal=(dx, axle_y, BEATER_AXLE_HEIGHT_M), lean_rad=math.atan2(reach, rise),
                  rest_rad=BEATER_REST_RAD, rod_length=math.hypot(reach, rise),
                  rod_radius=BEATER_ROD_RADIUS_M, ball_radius=BEATER_BALL_RADIUS_M)


def kit_hardware(kit: Kit) -> KitHardware:
    """The beaters and stand rods physics builds for ``kit`` (world metres): a beater on the kick pedal (BASS's
    ``pedal``), and on the left bass pedal of a double pedal, when the kit plays BASS (its object the kick, whatever
    the ids: :meth:`Kit.kick`); a stand rod under each mounted drum and cymbal (:func:`stand_rods`)."""
    kick = kit.kick()
    driving = {kit.kick_pedal()} | ({kit.left_bass_pedal} if kit.double_pedal and kit.left_bass_pedal else set())
    beaters = [] if kick is None else [_beater(kit, o, kick) for o in kit.objects
                                       if o.kind == "pedal" and o.id in driving]
    stands = [StandRod(top=(float(top[0]), float(top[1]), float(top[2])), height=height, radius=STAND_ROD_RADIUS_M)
              for top, height in stand_rods(kit.objects, None if kick is None else kick.id)]
    return KitHardware(beaters=beaters, stands=stands)
