"""The drummer scene: the 57-DOF percussionist on the throne at the whole kit.

Build order: kit bodies (common/kit.py), joint limits (pybullet's DeepMimic clips,
limits.py), the generated body (segment lengths from ``skeleton_bvh`` if given) pinned
to the throne, the rest posture (solved by IK: right stick over the hi-hat, left over
the snare, feet on their pedals for a right-handed kit; mirrored for a left-handed
one), the limits of the ``limits_from`` clips if given (mirror-symmetric unless ``asymmetric_limits``, grown where
they do not hold the rest posture), the controller.

Inputs, all timed in rig seconds and streamed ahead of time:

* Cartesian targets per limb (stick tips and balls of the feet) from
  :class:`~common.messages.physics.CartesianTarget` or a whole
  :class:`~common.gesture.plan.GesturePlan` (:meth:`DrummerScene.load_plan`);
* joint targets (57 angles and velocities) from
  :class:`~common.messages.physics.JointTarget`.

Modes: ``cartesian`` / ``cartesian_pd`` (DLS IK on the actual state every
step, feeding the computed-torque or the explicit PD); ``joint_pd`` /
``joint_spd`` / ``joint_ct`` (PD tracking joint targets; Cartesian targets are
first turned into joint targets by the same IK on a kinematic copy of the body,
open loop, as the paper's joint-space tracking of captured gestures). See
docs/physics.md.
"""

from __future__ import annotations

import bisect
import dataclasses
import logging
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from common.kit import FOOT_BALL_ALONG, FOOTBOARD_LENGTH_M, PEDAL_REST_ANGLE_RAD, EventType, Kit, Limb
from common.messages import OscMessage
from common.messages.physics import (
    CartesianTarget,
    JointTarget,
    PhysicsControlMode,
    PhysicsGains,
    PhysicsGrip,
    PhysicsIk,
)
from common.score.limbs import LimbLengths, pedals_out_of_reach
from services.physics.anthropometry import performer_anthropometry
from services.physics.body import LIMBS, Body
from services.physics.character import (
    DOF_NAMES,
    JOINT_GROUP,
    JOINTS,
    CharacterSpec,
    build_character,
    joint_kind,
)
from services.physics.contacts import ContactTracker, Striker
from services.physics.control import Controller
from services.physics.follow_through import LimbTrack, Strike
from services.physics.kernels import hermite_stray, stick_under_plate, swing_displacement
from services.physics.kitbodies import SLOW_SPRING_PERIOD_S, build_kit
from services.physics.limits import JointLimits, default_limits, limits_from_clips, load_clip, symmetric_limits
from services.physics.mocap import MotionClip
from services.physics.targets import TargetError, Track
from services.physics.urdf import Inertial, Link, Robot, Shape, load_robot
from services.physics.world import World, WorldSettings

if TYPE_CHECKING:
    from common.gesture.plan import GesturePlan, LimbTrajectory
    from services.physics.core import PhysicsSettings

log = logging.getLogger("batteur.physics")

N_DOF = len(DOF_NAMES)
STICK_DESCENT_DEG = 12.0
"""At rest a stick descends this much from the hand to the tip, degrees."""
FOOT_HOVER_M = 0.04
"""At rest the ball of each foot hovers this far above its footboard, metres (no weight on the pedal)."""
FOOT_STROKE_SPEED = 0.3
"""A foot whose target moves down faster than this (m/s) plays a pedal stroke: it presses the footboard."""
FOOT_TARGET_OFFSET_M = 0.035
"""A foot target is on the pedal's plate (the kit's pedal position: the footboard pressed flat); the ball of the
foot is then this far above it, metres (board thickness and the shoe's tilt; measured)."""
HIHAT_FOOT_AIM_M: tuple[tuple[float, float], ...] = (
    (1.2, -0.0275), (1.4, -0.0191), (1.5, -0.0190), (1.6, -0.0149), (1.7, -0.0046), (1.75, 0.0), (1.8, 0.0044),
    (1.9, 0.0126), (2.0, 0.0196), (2.2, 0.0301))
"""(drummer height m, how far the hi-hat foot's aim (and its rest) is raised above ``FOOT_TARGET_OFFSET_M``, metres;
negative: lowered). The shoe presses a footboard with its toe, ahead of the ball the planner aims (common/kit.py
``FOOT_PRESS_TABLE``, measured with the 1.75 m drummer); only the ball is controlled, so a shorter foot, pitched
flatter by a shorter leg on the same throne, leaves its toe higher and the board less pressed (1.4 m: 0.72
instead of 0.93 at the chick target, short of the plates' closing point), a longer one presses it flat. Measured
on the default kit (0.52 m throne, 73 kg): the shift that makes the foot held at the chick target press the
board 0.93, as the 1.75 m drummer's (docs/physics.md, "A small drummer's hi-hat foot")."""
FOOT_AIM_HEIGHT_M = 1.75
"""The drummer height the planner's foot heights were measured with (``common/kit.py`` ``FOOT_PRESS_TABLE``),
metres: the feet's aims are shifted from there."""
KICK_FOOT_AIM_PER_M = 0.0515
"""How far the bass-drum foot's aim (and its rest) is raised per metre of the drummer's height above
``FOOT_AIM_HEIGHT_M`` (negative below), metres per metre. As for the hi-hat foot (``HIHAT_FOOT_AIM_M``), the toe
presses the footboard ahead of the ball that is aimed, a shorter foot pitched flatter less deeply: a 1.4 m
drummer's soft kicks stopped the board short of the beater's contact (0.91 of its travel, 0.95 needed) and did not
sound, a 2.0 m drummer's sounded 14-19 ms earlier than the 1.75 m drummer's. The shift that gives kicks at
velocities 0.05-1.0 the 1.75 m drummer's timing (mean over seven kicks within 0.3 ms; default kit, 73 kg) was
measured at 1.2 to 2.2 m: it grows linearly with the height, within 1.1 mm of this slope (-19 mm at 1.4 m, +12.8
at 2.0 m; docs/physics.md, "A small or tall drummer's kick foot")."""
CYMBAL_AIM_ABOVE_M = 0.30
"""A hand target up to this far over a cymbal's plate follows the plate's swing (see :meth:`cartesian_targets`);
the share fades out over ``CYMBAL_AIM_REACH_M`` beyond it, beyond the rim and under the plate, metres."""
CYMBAL_AIM_BELOW_M = 0.03
CYMBAL_AIM_REACH_M = 0.08
CYMBAL_UNDER_CLEAR_M = 0.04
"""A stick under a cymbal's plate whose target would bring it this near the plate's underside (it would press the
plate up and, the target following the swing, hold it there) first goes out from under it, this far below the
plate and beyond its rim, then up beside the rim, and only then to its target (:meth:`DrummerScene._out_from_under`),
metres."""
CYMBAL_UNDER_STEP_M = 0.03
"""... aiming at most this far from where its bead is at each update (it moves out steadily), metres."""
CYMBAL_UNDER_MARGIN_M = 0.02
"""A point of a stick up to this far beyond a plate's rim and below its plane is under it, metres."""
_STICK_SAMPLES = np.array([1.0, 0.7, 0.4])
"""Points of a stick judged under a plate: fractions of the way from the wrist to the bead."""
LEAD_IN_RISE_M = 0.05
"""A hand moving from where it is to a plan's first knot passes this far above the higher of the two halfway, so
its stick clears what lies between (going from the rest over the hi-hat to the snare, a straight path met the
hi-hat's edge), metres."""
LEAD_IN_ARC_MIN_S = 0.2
"""Shorter moves to a plan's first knot go straight (an arc would ask for a rise at several metres per second)."""
JUMP_STROKE_BEFORE_S = 0.15
"""A live core's targets trailing the rig clock (skipped steps) do not jump to it (:meth:`DrummerScene.can_jump`)
from or to a time this long before a planned contact or less (the downstroke and the move to it), seconds, ..."""
JUMP_STROKE_AFTER_S = 0.08
"""... or this long after its planned bottom or less (the rebound), seconds, ..."""
JUMP_MAX_M = 0.02
"""... nor where a limb's target would move more than this at once, metres (by default), ..."""
JUMP_MAX_SPEED_M_S = 0.5
"""... or change its velocity more than this, m/s (by default), ..."""
JUMP_SAMPLE_S = 0.005
"""... nor where a limb's target strays more than that distance from where it is at the jump's start at any time
between its two ends, sampled this often and at every knot between, seconds (5 ms: every stroke of the demo's
plan has its target more than 2 cm off where it was 0.15 s before the contact for 136 ms or more, some 27
samples; the knots catch the bottom of a shorter one)."""


@dataclass(frozen=True)
class GripSpec:
    """Forearm pronation (elbow z, radians; right side, left mirrored) and fulcrum spring stiffness (N m/rad)."""

    pronation: float
    k_pitch: float
    k_yaw: float


GRIPS: dict[str, GripSpec] = {
    "french": GripSpec(0.0, 15.0, 60.0),  # palms facing, thumbs up: the stick pivots about the hand's x
    "german": GripSpec(math.radians(80.0), 60.0, 15.0),  # palms down: it pivots about the stick frame's z
    "american": GripSpec(math.radians(45.0), 20.0, 20.0),  # matched, in between
    "traditional": GripSpec(math.radians(45.0), 20.0, 20.0),  # the leading hand as american; the other underhand
}
"""Soft fingers in the stroke direction (15-20 N m/rad): the stick rebounds in the hand while the hand follows
through (stiffer fingers press the stick into the head for 20-30 ms at 3 m/s)."""
TRADITIONAL_UNDERHAND = GripSpec(math.radians(-60.0), 15.0, 60.0)
"""The traditional grip's underhand hand: the snare hand, the one that does not lead (the left on a right-handed
kit, the right on a left-handed one: :func:`underhand_side`); its pronation on that side's sign, so it mirrors."""
FINGER_INERTIA_KGM2 = 1.2e-3
"""The stick's moment of inertia about the fulcrum that the finger springs' damping is scaled by, kg m^2."""
FINGER_DAMPING_RATIO = 0.3

SWITCH_LOG_INTERVAL_S = 1.0
"""Live switches (control mode, gains, IK parameters, grip) are logged, each kind and group (or hand) at most once per
this many seconds of rig time: a stream of them is held, and its latest said with their count once the interval has
passed (:meth:`DrummerScene.flush_switches`, from the node's step loop, or with the next switch)."""
LOW_KS_SCALE = 0.15
"""A live gains message scaling a group's stiffness below this (of the defaults) is warned: the quaternion limits'
restoring torque is proportional to ks, and below it they no longer hold. Measured on tests/render/short_groove.txt
(cartesian, arms scaled): limit violations 185 at x1, 149 at x0.25, 256 at x0.15, 1408 at x0.1 (sticks at up to
18 m/s), 6506 at x0.05 (45 m/s); joint_pd held down to x0.05 and broke at 0 (docs/physics.md, "Live gains"), so
its own threshold is :data:`LOW_KS_SCALE_BY_MODE`'s."""
LOW_KS_SCALE_BY_MODE: dict[str, float] = {"joint_pd": 0.05}
"""Control modes measured to hold the limits lower than :data:`LOW_KS_SCALE` -> the scale below which they break."""

_LIMIT_CACHE: dict[str, JointLimits] = {}
_CLIP_CACHE: dict[tuple[str, ...], list[MotionClip]] = {}


def cached_default_limits() -> JointLimits:
    """DeepMimic limits are the same for every drummer; compute them once per process. Mirror-symmetric
    (:func:`limits.symmetric_limits`): a body's two sides have the same range, whichever side the clips favour."""
    if "default" not in _LIMIT_CACHE:
        _LIMIT_CACHE["default"] = symmetric_limits(default_limits())
    return _LIMIT_CACHE["default"]


def cached_clips(sources: tuple[str, ...]) -> list[MotionClip]:
    """The motion clips of ``limits_from`` (:func:`limits.load_clip`: BVH files, DeepMimic files or names), read
    once per process; ``ValueError`` / ``FileNotFoundError`` naming a file that cannot be read."""
    if sources not in _CLIP_CACHE:
        _CLIP_CACHE[sources] = [load_clip(source) for source in sources]
    return _CLIP_CACHE[sources]


def posture_limits(clips: list[MotionClip], posture: np.ndarray, symmetric: bool = True) -> JointLimits:
    """Limits from ``clips`` that hold the playing ``posture`` (57,) radians: a joint the clips never bring
    there keeps a box grown to it (:func:`limits.limits_from_clips`, ``+posture`` in its sources). ``symmetric``:
    the clips' boxes mirror-symmetric first (:func:`limits.symmetric_limits`, as the default limits: a side the
    clips let reach further drifted there and lost fast kicks); False keeps each side's own estimate (a performer
    with a real asymmetry: ``asymmetric_limits``)."""
    need = {joint: posture[3 * k:3 * k + 3] for k, joint in enumerate(JOINTS)}
    return limits_from_clips(clips, must_contain=need, symmetric=symmetric)


def initial_guess(grip: str, handedness: str = "right") -> np.ndarray:
    """A seated playing posture to start the rest-posture IK from (57,) radians, for a kit of ``handedness``."""
    q = np.zeros(N_DOF)

    def put(joint: str, x: float = 0.0, y: float = 0.0, z: float = 0.0) -> None:
        i = JOINTS.index(joint) * 3
        q[i:i + 3] = (x, y, z)

    put("lumbar", -0.08)
    put("thoracic", -0.05)
    for side, sx in (("left", -1.0), ("right", 1.0)):
        g = grip_for(grip, side, handedness)
        put(f"{side}_shoulder", 0.45, -sx * 0.3, 0.0)
        put(f"{side}_elbow", 1.2, 0.0, sx * g.pronation)
        put(f"{side}_wrist", -0.2, 0.0, 0.0)
        put(f"{side}_hip", 1.35, -sx * 0.15, 0.0)
        put(f"{side}_knee", -1.5, 0.0, 0.0)
        put(f"{side}_ankle", 0.1, 0.0, 0.0)
    return q


def underhand_side(handedness: str) -> str:
    """The hand a traditional grip holds underhand on a kit of ``handedness`` (``Kit.handedness``): the one that
    does not lead, the snare hand (until 7 Dec the left whatever the kit: a left-handed drummer's leading hand)."""
    return "right" if handedness == "left" else "left"


def grip_for(grip: str, side: str, handedness: str = "right") -> GripSpec:
    """The ``side`` hand's grip spec holding ``grip`` on a kit of ``handedness`` (traditional: the hand of
    :func:`underhand_side` underhand, the other as american)."""
    if grip not in GRIPS:
        raise TargetError(f"unknown grip {grip!r} (known: {', '.join(GRIPS)})")
    if grip == "traditional" and side == underhand_side(handedness):
        return TRADITIONAL_UNDERHAND
    return GRIPS[grip]


def hihat_foot_aim_m(height_m: float) -> float:
    """How far the hi-hat foot's aim is raised for a drummer ``height_m`` tall, metres (``HIHAT_FOOT_AIM_M``
    interpolated; 0 for the 1.75 m drummer the planner's foot heights were measured with)."""
    heights, shifts = zip(*HIHAT_FOOT_AIM_M, strict=True)
    return float(np.interp(height_m, heights, shifts))


def kick_foot_aim_m(height_m: float) -> float:
    """How far the bass-drum foot's aim (and its rest) is raised for a drummer ``height_m`` tall, metres
    (``KICK_FOOT_AIM_PER_M``; 0 for the 1.75 m drummer)."""
    return KICK_FOOT_AIM_PER_M * (height_m - FOOT_AIM_HEIGHT_M)


def footboard_point(position: tuple[float, float, float], along: float = FOOT_BALL_ALONG) -> np.ndarray:
    """A point on a pedal's footboard top surface at rest, ``along`` its length from the heel (metres)."""
    heel = np.array(position) + np.array([0.0, -FOOTBOARD_LENGTH_M / 2, 0.0])
    d = along * FOOTBOARD_LENGTH_M
    return heel + np.array([0.0, d * math.cos(PEDAL_REST_ANGLE_RAD), d * math.sin(PEDAL_REST_ANGLE_RAD) + 0.012])


def solve_posture(body: Body, targets: dict[str, np.ndarray], q0: np.ndarray, clamp: Any,
                  iterations: int = 60, damping: float = 0.05, frozen: np.ndarray | None = None,
                  rest: np.ndarray | None = None, posture_gain: float = 0.0,
                  extra: dict[int, np.ndarray] | None = None) -> tuple[np.ndarray, float]:
    """Kinematic DLS IK (teleports the body): joint angles (57,) reaching ``targets`` {limb: (3,)}; max error m.

    ``extra``: more point targets {link index: (3,)} (e.g. where the hands hold the sticks, which sets the
    sticks' direction); ``frozen``: DOF that keep ``q0``.
    """
    q = q0.copy()
    rows = [LIMBS.index(limb) for limb in LIMBS if limb in targets]
    links = [body.effector_links[LIMBS[r]] for r in rows] + list((extra or {}).keys())
    goals = [targets[LIMBS[r]] for r in rows] + list((extra or {}).values())
    free = np.ones(N_DOF, dtype=bool) if frozen is None else ~frozen
    err_max = math.inf
    for _ in range(iterations):
        body.set_state(q)
        eff, jac = body.kinematics(links)
        err = np.concatenate([g - e for g, e in zip(goals, eff, strict=True)])
        err_max = float(np.max(np.abs(err)))
        if err_max < 2e-4:
            break
        j = jac.reshape(3 * len(links), -1) * free[None, :]
        inv = np.linalg.inv(j @ j.T + damping**2 * np.eye(j.shape[0]))
        dq = j.T @ (inv @ err)
        if rest is not None and posture_gain > 0:
            post = posture_gain * (rest - q) * free
            dq += post - j.T @ (inv @ (j @ post))
        q = clamp(q + dq)
    return q, err_max


class DrummerScene:
    """The percussionist at the kit (see the module docstring)."""

    def __init__(self, world: World, kit: Kit, settings: PhysicsSettings, limits: JointLimits | None = None) -> None:
        self.world = world
        self.kit = kit
        self.settings = settings
        # the rest posture is solved within the DeepMimic limits; the clips of limits_from then replace them
        self.limits = limits if limits is not None else cached_default_limits()
        self.kit_bodies = build_kit(world, kit)
        self.seat_position = tuple(kit.seat_position())  # the planner's reach (common/score/limbs.py) starts here too
        self._floor(world)
        self.anthro = performer_anthropometry(settings.height_m, settings.mass_kg, settings.skeleton_bvh,
                                              settings.skeleton_units)
        self.spec = CharacterSpec(self.anthro, limits=self.limits.dof_limits())
        self.model = build_character(self.spec)
        self.body = Body(world, self.model, self.seat_position,  # type: ignore[arg-type]
                         floating_base=settings.floating_base)
        self.grip: dict[str, str] = {"left": settings.grip, "right": settings.grip}
        self._finger_gains: tuple[np.ndarray, np.ndarray] | None = None
        """Fulcrum spring stiffness and damping for the grips (N m/rad, N m s/rad), set from ``grip``."""
        # rest posture by IK, then the controller
        self.rest_targets = self._rest_targets()
        guess = initial_guess(settings.grip, kit.handedness)
        frozen = np.zeros(N_DOF, dtype=bool)
        for side in ("left", "right"):
            frozen[JOINTS.index(f"{side}_elbow") * 3 + 2] = True
        frozen[0:3] = True  # the seat joint stays upright at rest
        clamp = _box_clamp(self.body)
        self.body.set_state(guess)
        extra = self._stick_holds()
        self.rest, self.rest_error = solve_posture(self.body, self.rest_targets, guess, clamp, iterations=300,
                                                   frozen=frozen, rest=guess, posture_gain=0.05, extra=extra)
        if limits is None and settings.limits_from:
            self.limits = posture_limits(cached_clips(settings.limits_from), self.rest,
                                         symmetric=not settings.asymmetric_limits)
            self.body.set_limits(self.limits.dof_limits())
            if (dropped := self.limits.dropped_summary()) is not None:  # said: the limits are not what was asked
                log.warning("joint limits from %s: %s", ", ".join(settings.limits_from), dropped)
        self.controller = Controller(world, self.body, self.limits, self.rest)
        self.rest = self.controller.clamp_targets(self.rest)
        self.controller.rest = self.rest.copy()
        self.controller.mode = settings.control
        self.control_every = max(1, round(settings.rate_hz / settings.control_rate_hz))
        """Physics steps per full control update (1: every step)."""
        self.controller.control_dt = self.control_every * world.dt
        self._steps_to_update = 0
        self._last_update_s = 0.0
        self._touching_at_update: frozenset[str] = frozenset()
        self.body.set_state(self.rest)
        self._kin: tuple[World, Body] | None = None
        self._kin_q = self.rest.copy()
        self.limb_tracks: dict[str, LimbTrack] = {limb: LimbTrack() for limb in LIMBS}
        self._last_touch: dict[str, dict[str, float]] = {limb: {} for limb in LIMBS}
        """Limb -> instrument -> when its striker (stick, beater) last touched it, rig seconds (strokes follow
        through until it does)."""
        self._around: dict[str, int] = {}
        """Hand -> the cymbal (index in ``cymbal_hinges``) its stick is getting out from under
        (:meth:`_out_from_under`)."""
        self._plate_side: dict[str, np.ndarray] = {}
        """Hand -> the side of each cymbal's plate its bead came to it from (:func:`stick_under_plate`)."""
        self.joint_track = Track(N_DOF)
        self.posture_track = Track(N_DOF)
        """Cartesian modes: a posture (57 angles, rad, and rates, rad/s) for the IK's null space instead of the
        rest posture, e.g. the captured joint trajectory of a gesture whose stick tips are the targets."""
        hihat_pedal = self.kit_bodies.hihat.pedal if self.kit_bodies.hihat is not None else None
        self._beater_pedals = [pedal for pedal in self.kit_bodies.pedals.values() if pedal is not hihat_pedal]
        self._beater_pedal_bodies = {pedal.body for pedal in self._beater_pedals}
        """Pedals a resting foot must not press (their beaters would rest on the head); the hi-hat foot presses
        its pedal to the plan's depth (a closed hi-hat is held closed by the foot)."""
        bass_foot, other_foot = ("left_foot", "right_foot") if kit.handedness == "left" else ("right_foot",
                                                                                              "left_foot")
        self._striker_limbs = {stick: hand for hand, stick in _HAND_STICKS} | {
            part: bass_foot if pedal.object_id == kit.kick_pedal() else other_foot
            for pedal in self._beater_pedals for part in pedal.beater_parts}
        """Striker part -> the limb that plays it (the second bass pedal's beater: the hi-hat foot's)."""
        self._feet = [(f"{side}_foot", self.body.link_ref[self.body.link_index[f"{side}_foot"]])
                      for side in ("left", "right")]
        """(limb, its foot's (body, link)), for the pedal contacts of each update."""
        self.tracker = ContactTracker(world, self.kit_bodies)
        self.tracker.instrument_every = max(1, round(SLOW_SPRING_PERIOD_S / world.dt))  # with the kit's readings
        for side in ("left", "right"):
            self.tracker.add_striker(Striker(self.body.id, self.body.link_index[f"{side}_stick"], f"{side}_stick",
                                             stick=self.spec.stick, side=side))
        self.pose_links: list[tuple[str, int, int]] = [
            (name, *self.body.link_ref[self.body.link_index[name]]) for name in self.model.segments
        ] + self.kit_bodies.pose_links
        self.reach = self._reach()
        bead = np.array([0.0, 0.0, self.spec.stick.tip_radius_m])
        sole = np.array([0.0, 0.0, FOOT_TARGET_OFFSET_M])
        self.target_offset = {limb: bead if limb.endswith("hand") else sole for limb in LIMBS}
        for foot in ("left_foot", "right_foot"):
            self.target_offset[foot] = sole + np.array([0.0, 0.0, self._foot_aim(foot)])
        self.last_targets: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        self.head: tuple[Any, float] | None = None
        """The plan's head trajectory (look-at point, nod) and its time offset, if any."""
        self.last_joint_target: tuple[np.ndarray, np.ndarray] = (self.rest.copy(), np.zeros(N_DOF))
        self._switch_logged: dict[tuple[str, str], float] = {}
        """(kind of live switch: control, gains, ik, grip, low_gains; its group or hand, '' for none) -> rig time its
        last line was logged, s."""
        self._switch_held: dict[tuple[str, str], tuple[int, int, str]] = {}
        """(kind, group) -> (switches not logged since, the latest's level, its line) (:meth:`_said_switch`)."""

    # ------------------------------------------------------------------ construction helpers

    def _floor(self, world: World) -> None:
        robot = Robot("floor")
        robot.add_link(Link("floor", Inertial(0.0), (Shape("box", (4.0, 4.0, 0.1), xyz=(0, 0, -0.05),
                                                             rgba=(0.3, 0.3, 0.3, 1.0)),)))
        self.floor = load_robot(world.client, robot, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0), fixed_base=True)

    def _foot_aim(self, limb: str) -> float:
        """How far ``limb``'s aim and rest are raised for this drummer's height, metres: a foot presses a footboard
        with its toe, ahead of the ball it is placed by, so a smaller foot pitched flatter presses less at the same
        ball height (0 for the 1.75 m drummer; ``HIHAT_FOOT_AIM_M``, ``KICK_FOOT_AIM_PER_M``)."""
        hihat_foot = "right_foot" if self.kit.handedness == "left" else "left_foot"
        height_m = self.settings.height_m
        return hihat_foot_aim_m(height_m) if limb == hihat_foot else kick_foot_aim_m(height_m)

    def _rest_targets(self) -> dict[str, np.ndarray]:
        kit = self.kit
        left_is_lead = kit.handedness == "right"
        out: dict[str, np.ndarray] = {}

        def above(event: EventType, height: float) -> np.ndarray | None:
            if event not in kit.events:
                return None
            spec = kit.events[event]
            obj = kit.object(spec.object)
            r = spec.r * obj.radius
            local = (r * math.cos(spec.theta), r * math.sin(spec.theta), 0.0)
            world = np.asarray(obj.to_world(local)) if hasattr(obj, "to_world") else np.asarray(obj.position)
            return world + np.asarray(obj.normal()) * height

        snare = above(EventType.SNARE, 0.08)
        hihat = above(EventType.HIHATCLOSED, 0.10)
        lead_hand, other_hand = ("right_hand", "left_hand") if left_is_lead else ("left_hand", "right_hand")
        if hihat is not None:
            out[lead_hand] = hihat
        if snare is not None:
            out[other_hand] = snare
        # the planner's reach, measured (common/score/limbs.py FOOT_REACH): until 7 Dec thigh + shank + foot, 1.12 m,
        # rested a foot on a pedal 1.04-1.12 m away that it could not play from
        legs = None if self.settings.skeleton_bvh is None else \
            LimbLengths.of_segments({name: s.length_m for name, s in self.anthro.segments.items()})  # as a render's
        far = pedals_out_of_reach(kit, self.settings.height_m, legs)
        for limb, pedal_id in (("right_foot", kit.kick_pedal()), ("left_foot", kit.hihat_pedal())):
            if kit.handedness == "left":
                limb = "left_foot" if limb == "right_foot" else "right_foot"
            if pedal_id is None:  # the kit plays no BASS (HIHATPEDAL): that foot rests where it stands
                continue
            pedal = kit.object(pedal_id)  # the kit checks its events' pedals exist
            target = footboard_point(pedal.position) + np.array([0.0, 0.0, FOOT_HOVER_M + self._foot_aim(limb)])
            if Limb(limb) in far.get(pedal_id, {}):  # stretched for it, the leg pulled the body (and hands) along
                continue  # the foot rests where it stands; the planner drops its notes (common/score/limbs.py)
            out[limb] = target
        return out

    def _stick_holds(self) -> dict[int, np.ndarray]:
        """Where each hand holds its stick at rest: behind and above the tip, toward the shoulder, so the stick
        points at its instrument descending ``STICK_DESCENT_DEG`` (link index of the fulcrum -> (3,) metres)."""
        out: dict[int, np.ndarray] = {}
        for limb in ("left_hand", "right_hand"):
            if limb not in self.rest_targets:
                continue
            side = limb.split("_")[0]
            tip = self.rest_targets[limb]
            shoulder, _ = self.body.link_pose(self.body.joint_index[f"{side}_shoulder_x"])
            back = shoulder - tip
            back[2] = 0.0
            back /= max(float(np.linalg.norm(back)), 1e-9)
            a = math.radians(STICK_DESCENT_DEG)
            reach = self.spec.stick.tip_offset
            hold = tip + reach * (math.cos(a) * back + np.array([0.0, 0.0, math.sin(a)]))
            out[self.body.link_index[f"{side}_fulcrum"]] = hold
        return out

    def _reach(self) -> dict[str, tuple[np.ndarray, float]]:
        """Per limb: the root joint's rest position and the maximum reach (metres), for validating targets."""
        seg = self.anthro.segments
        arm = seg["clavicle"].length_m + seg["upper_arm"].length_m + seg["forearm"].length_m + \
            seg["hand"].length_m + self.spec.stick.tip_offset + 0.35  # + the trunk leaning
        leg = seg["thigh"].length_m + seg["shank"].length_m + seg["foot"].length_m
        out: dict[str, tuple[np.ndarray, float]] = {}
        for limb, joint, reach in (("left_hand", "left_clavicle_x", arm), ("right_hand", "right_clavicle_x", arm),
                                   ("left_foot", "left_hip_x", leg), ("right_foot", "right_hip_x", leg)):
            pos, _ = self.body.link_pose(self.body.joint_index[joint])
            out[limb] = (pos, reach)
        return out

    # ------------------------------------------------------------------ inputs

    def check_cartesian(self, limb: str, position: np.ndarray) -> None:
        if limb not in self.limb_tracks:
            raise TargetError(f"unknown limb {limb!r} (known: {', '.join(LIMBS)})")
        if not np.all(np.isfinite(position)):
            raise TargetError(f"{limb} target {position.tolist()} is not finite")
        root, reach = self.reach[limb]
        dist = float(np.linalg.norm(position - root))
        if dist > reach:
            raise TargetError(f"{limb} target {np.round(position, 3).tolist()} is unreachable: "
                              f"{dist:.2f} m from the limb's root, reach {reach:.2f} m")

    def check_cartesian_rows(self, limb: str, positions: np.ndarray) -> None:
        """:meth:`check_cartesian` for every row of ``positions`` (n, 3) at once (metres): raises for the first row
        that is not finite or out of reach, with that row's message."""
        if limb not in self.limb_tracks:
            raise TargetError(f"unknown limb {limb!r} (known: {', '.join(LIMBS)})")
        rows = np.asarray(positions, dtype=float).reshape(-1, 3)
        root, reach = self.reach[limb]
        with np.errstate(invalid="ignore"):
            bad = ~np.all(np.isfinite(rows), axis=1) | (np.linalg.norm(rows - root, axis=1) > reach)
        first = np.flatnonzero(bad)
        if first.size:
            self.check_cartesian(limb, rows[first[0]])

    def add_cartesian(self, limb: str, time: float, position: np.ndarray, velocity: np.ndarray, now: float,
                      lag: float = 0.0) -> None:
        """Queue one Cartesian waypoint (rig time s, metres, m/s) ``lag`` seconds earlier on the targets' clock (a
        live core's targets trailing the rig clock by that much: it is reached at its rig time); raises
        :class:`TargetError` (a rig time before ``now`` s is past)."""
        position = np.asarray(position, dtype=float)
        velocity = np.asarray(velocity, dtype=float)
        if position.shape != (3,) or velocity.shape != (3,):
            raise TargetError(f"a Cartesian target needs 3 coordinates and 3 velocities, "
                              f"got {position.size} and {velocity.size}")
        if not math.isfinite(time):
            raise TargetError("target time is not finite")
        if time < now - 1e-9:
            raise TargetError(f"{limb} target at {time:.4f} s is in the past (now {now:.4f} s)")
        self.check_cartesian(limb, position)
        if not np.all(np.isfinite(velocity)):
            raise TargetError(f"{limb} target velocity {velocity.tolist()} is not finite")
        self.limb_tracks[limb].add(time - lag, position, velocity)

    def add_joints(self, time: float, values: np.ndarray | tuple[float, ...], now: float, lag: float = 0.0) -> None:
        """Queue one joint waypoint at rig time ``time`` (s): 57 angles (rad) then 57 velocities (rad/s), ``lag``
        seconds earlier on the targets' clock (as :meth:`add_cartesian`); raises :class:`TargetError`."""
        v = np.asarray(values, dtype=float).reshape(-1)
        if v.size != 2 * N_DOF:
            raise TargetError(f"joint target needs {2 * N_DOF} values ({N_DOF} angles then {N_DOF} velocities), "
                              f"got {v.size}")
        if not np.all(np.isfinite(v)) or not math.isfinite(time):
            bad = [DOF_NAMES[i % N_DOF] for i in np.flatnonzero(~np.isfinite(v))[:3]]
            raise TargetError(f"joint target has non-finite values (first: {', '.join(bad) or 'time'})")
        if time < now - 1e-9:
            raise TargetError(f"joint target at {time:.4f} s is in the past (now {now:.4f} s)")
        q = v[:N_DOF]
        tol = 1e-3
        out = np.flatnonzero((q < self.body.lower - tol) | (q > self.body.upper + tol))
        if out.size:
            i = int(out[0])
            raise TargetError(f"joint target {DOF_NAMES[i]} = {math.degrees(q[i]):.1f} deg is outside its limits "
                              f"[{math.degrees(self.body.lower[i]):.1f}, {math.degrees(self.body.upper[i]):.1f}] deg"
                              f"{f' (and {out.size - 1} more)' if out.size > 1 else ''}")
        self.joint_track.add(time - lag, q, v[N_DOF:])

    def add_posture(self, time: float, values: np.ndarray | tuple[float, ...], now: float) -> None:
        """Queue one null-space posture knot for the Cartesian modes: 57 angles (rad) then 57 rates (rad/s).

        The IK then keeps the arms, trunk and head near this posture while the stick tips and feet follow their
        targets (Algorithm 2's posture term); outside the joint limits it is projected inside. Raises
        :class:`TargetError` like :meth:`add_joints`."""
        v = np.asarray(values, dtype=float).reshape(-1)
        if v.size != 2 * N_DOF:
            raise TargetError(f"a posture needs {2 * N_DOF} values ({N_DOF} angles then {N_DOF} rates), got {v.size}")
        if not np.all(np.isfinite(v)) or not math.isfinite(time):
            raise TargetError("posture has non-finite values")
        if time < now - 1e-9:
            raise TargetError(f"posture at {time:.4f} s is in the past (now {now:.4f} s)")
        self.posture_track.add(time, self.controller.clamp_targets(v[:N_DOF]), v[N_DOF:])

    def load_plan(self, plan: GesturePlan, start_at: float, now: float | None = None) -> None:
        """Track a whole gesture plan: its time ``plan.start_time`` maps to rig time ``start_at`` (seconds).

        Every knot is checked first (nothing is queued if one is unreachable, or if a limb's knots with its
        lead-in would pass its track's ``max_knots``: :class:`TargetError`, every track kept as it was). When
        the plan starts later than ``now``, each limb first moves smoothly from where it is to the plan's first
        knot (a hand, given ``LEAD_IN_ARC_MIN_S`` or more, over an arc ``LEAD_IN_RISE_M`` above the higher end).
        """
        offset = start_at - plan.start_time
        names = {limb: str(limb.value if hasattr(limb, "value") else limb) for limb in plan.trajectories}
        for limb, traj in plan.trajectories.items():
            name = names[limb]
            if name not in self.limb_tracks:
                raise TargetError(f"plan has unknown limb {name!r}")
            # checked here, not when queued: queueing clears the limb's track first
            times = np.asarray(traj.times, dtype=float) + offset
            if not (np.all(np.isfinite(times)) and np.all(np.diff(times) > 0)):
                raise TargetError(f"plan's {name} knot times, started at {start_at} s, are not finite and "
                                  "strictly increasing")
            self.check_cartesian_rows(name, traj.positions)
        here = self.current_targets()
        lead_ins = {limb: self._lead_in(names[limb], traj, offset, here, now)
                    for limb, traj in plan.trajectories.items()}
        for limb, traj in plan.trajectories.items():  # before any track is cleared: a refusal keeps them all
            self._check_plan_room(names[limb], len(traj.times), len(lead_ins[limb]))
        self.head = (plan.head, offset) if plan.head is not None else None
        for limb, traj in plan.trajectories.items():
            track = self.limb_tracks[names[limb]]
            track.clear()
            for knot in lead_ins[limb]:
                track.add(*knot)
            track.extend(traj.times + offset, traj.positions, traj.velocities)
            track.add_strokes(plan.strokes_of(limb), offset)

    def _lead_in(self, name: str, traj: LimbTrajectory, offset: float, here: dict[str, np.ndarray],
                 now: float | None) -> list[tuple[float, np.ndarray, np.ndarray]]:
        """The knots (rig time s, m, m/s) that bring limb ``name`` from where it is to its plan's first knot: none
        when the plan starts now (or ``now`` is unknown), else a start knot, and a hand's arc apex if time allows."""
        first = traj.times[0] + offset
        if now is None or first <= now + 1e-3:
            return []
        knots = [(now, here[name], np.zeros(3))]
        if name in _HANDS and first - now >= LEAD_IN_ARC_MIN_S:
            knots.append(_lead_in_apex(now, here[name], first, np.asarray(traj.positions[0], dtype=float)))
        return knots

    def _check_plan_room(self, name: str, knots: int, lead_in: int) -> None:
        """Raise :class:`TargetError` if ``knots`` plan knots after ``lead_in`` lead-in knots would pass limb
        ``name``'s track bound (the track is cleared first, so nothing queued counts)."""
        bound = self.limb_tracks[name].max_knots
        if knots + lead_in > bound:
            raise TargetError(f"plan has {knots} {name} knots; with the {lead_in} lead-in knots that passes the limit "
                              f"of {bound} knots per track (MAX_TRACK_KNOTS); refused, the queued targets are kept")

    def current_targets(self) -> dict[str, np.ndarray]:
        """Where each limb's target point is now (the inverse of the hands' bead offset), metres."""
        self.body.update()
        eff, _ = self.body.kinematics()
        return {limb: eff[i] - self.target_offset[limb] for i, limb in enumerate(LIMBS)}

    def handle(self, message: OscMessage, now: float, lag: float = 0.0) -> None:
        """Act on a drummer message at rig time ``now`` (s); streamed targets are queued ``lag`` seconds earlier on
        the targets' clock (a live core's targets trailing the rig clock by that much: they play at their rig
        times)."""
        if isinstance(message, CartesianTarget):
            self.add_cartesian(message.limb, message.time, np.array([message.x, message.y, message.z]),
                               np.array([message.vx, message.vy, message.vz]), now, lag)
        elif isinstance(message, JointTarget):
            self.add_joints(message.time, message.values, now, lag)
        elif isinstance(message, PhysicsControlMode):
            before = self.controller.mode
            self.controller.mode = message.mode
            self.controller.reset_reference()
            self._said_switch("control", now, "control mode %s -> %s", before, message.mode)
        elif isinstance(message, PhysicsGains):
            self._set_gains(message, now)
        elif isinstance(message, PhysicsIk):
            params = self.controller.params
            self.controller.set_params(dataclasses.replace(params, ik_damping=message.damping,
                                                           posture_gain=message.posture_gain))
            self._said_switch("ik", now, "IK damping %g -> %g m, posture gain %g -> %g 1/s", params.ik_damping,
                              message.damping, params.posture_gain, message.posture_gain)
        elif isinstance(message, PhysicsGrip):
            before = ", ".join(f"{side} {self.grip[side]}" for side in ("left", "right"))
            self.set_grip(message.hand, message.grip)
            self._said_switch(("grip", message.hand), now, "grip %s -> %s (hand %s)", before,
                              ", ".join(f"{side} {self.grip[side]}" for side in ("left", "right")), message.hand)

    def _set_gains(self, message: PhysicsGains, now: float) -> None:
        """Scale a group's gains (:meth:`Controller.set_gains`); said (what from what), and warned when the
        stiffness is so low that the joint limits no longer hold (``LOW_KS_SCALE``)."""
        controller = self.controller
        mask = np.ones(len(controller.ks), dtype=bool) if message.group == "all" else \
            controller.group_of == message.group
        before = (_scales(controller.scale_ks[mask]), _scales(controller.scale_kd[mask]))
        controller.set_gains(message.group, message.ks_scale, message.kd_scale)
        self._said_switch(("gains", message.group), now, "gains %s: ks x%s -> x%g, kd x%s -> x%g (of the defaults)",
                          message.group,
                          before[0], message.ks_scale, before[1], message.kd_scale)
        limited = {JOINT_GROUP[joint_kind(joint)] for joint in controller.q_joints}
        mode = controller.mode
        low = LOW_KS_SCALE_BY_MODE.get(mode, LOW_KS_SCALE)  # joint_pd measured to hold the limits lower
        if message.ks_scale < low and (message.group == "all" or message.group in limited):
            self._said_switch(("low_gains", message.group), now, "gains %s: ks x%g is below x%g in %s control: the "
                              "joint limits' restoring torque scales with ks, and below it the limits no longer hold "
                              "(joints leave their ellipsoids, sticks strike at 10-45 m/s; docs/physics.md, \"Live "
                              "gains\")", message.group, message.ks_scale, low, mode, warning=True)

    def _said_switch(self, kind: str | tuple[str, str], now: float, text: str, *args: object,
                     warning: bool = False) -> None:
        """Log an accepted switch (INFO; ``warning``: WARNING), each ``kind`` (with its group or hand: a burst
        setting trunk, head, arms and legs says all four) at most once per ``SWITCH_LOG_INTERVAL_S`` of rig time
        ``now`` (s): a stream of them is held, the latest said with their count once the interval has passed
        (:meth:`flush_switches`; until 7 Dec a slider's last value was never said)."""
        key = (kind, "") if isinstance(kind, str) else kind
        self.flush_switches(now, but=key)
        level = logging.WARNING if warning else logging.INFO
        last = self._switch_logged.get(key)
        if last is not None and 0.0 <= now - last < SWITCH_LOG_INTERVAL_S:
            count = self._switch_held[key][0] if key in self._switch_held else 0
            self._switch_held[key] = (count + 1, level, text % args)
            return
        self._switch_logged[key] = now
        held = self._switch_held.pop(key, None)  # this line says where they led
        log.log(level, "%s%s", text % args, f" (+{held[0]} more since the last report)" if held else "")

    def flush_switches(self, now: float, but: tuple[str, str] | None = None) -> None:
        """Log each held switch (:meth:`_said_switch`) whose interval has passed at rig time ``now`` (s), but ``but``
        (said by the switch logging now): its latest line, with how many it stands for."""
        for key, (count, level, line) in list(self._switch_held.items()):
            if key != but and not 0.0 <= now - self._switch_logged[key] < SWITCH_LOG_INTERVAL_S:
                del self._switch_held[key]
                self._switch_logged[key] = now
                log.log(level, "%s (the latest of %d since the last report)", line, count)

    def set_grip(self, hand: str, grip: str) -> None:
        """Change the grip live: the forearm pronation of the rest posture and the fulcrum springs."""
        sides = ("left", "right") if hand == "both" else (hand,)
        for side in sides:
            if side not in self.grip:
                raise TargetError(f"unknown hand {side!r}")
            spec = grip_for(grip, side, self.kit.handedness)
            self.grip[side] = grip
            sx = 1.0 if side == "right" else -1.0
            self.rest[JOINTS.index(f"{side}_elbow") * 3 + 2] = sx * spec.pronation
        self.controller.rest = self.rest.copy()
        self._finger_gains = None

    def reset(self) -> None:
        self._steps_to_update = 0
        self._last_touch = {limb: {} for limb in LIMBS}
        self._around.clear()
        self._plate_side.clear()
        for track in self.limb_tracks.values():
            track.clear()
        self.joint_track.clear()
        self.posture_track.clear()
        self.controller.posture_rate = None
        self.body.restore_bases()
        self.body.set_state(self.rest)
        self._kin_q = self.rest.copy()
        self.controller.rest = self.rest.copy()
        self.head = None
        self.controller.reset_reference()

    # ------------------------------------------------------------------ stepping

    def close(self) -> None:
        """Disconnect the helper clients (kinematic copy, inverse dynamics copy)."""
        if self._kin is not None:
            self._kin[0].close()
            self._kin = None
        self.controller.close()

    def _kinematic(self) -> Body:
        """A kinematic copy of the body in its own world (for open-loop IK in joint modes)."""
        if self._kin is None:
            kin_world = World(WorldSettings(timestep_s=self.world.dt))
            self._kin = (kin_world, Body(kin_world, self.model, self.seat_position))  # type: ignore[arg-type]
        return self._kin[1]

    def cartesian_targets(self, t: float) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Effector targets at rig time ``t``: {limb: (aim point (3,) m, velocity (3,) m/s)}.

        A hand's target is where its bead touches (the stick's lowest point, as the gesture planner
        gives hit points on the surface); the controlled aim point is the bead centre, one bead radius up.
        The planner aims at cymbals at rest; a hand target over a swinging cymbal is carried along with the
        plate (as a drummer follows the cymbal with the eye), else a knocked, tilted ride stays under the
        stick's planned lift and the stick rests on it, pressing it, instead of striking it. A stick under a
        plate whose target is over it goes around the rim first (:meth:`_out_from_under`), else it would be
        pulled up into the plate and, the target rising with the swing it causes, hold it up, pressed.
        """
        out: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        hinges = self.kit_bodies.cymbal_hinges
        swinging = hinges is not None and hinges.swinging
        for limb, track in self.limb_tracks.items():
            if len(track):
                track.prune(t - 1.0)
                late = track.follow_through(t, self._last_touch[limb])
                pos, vel = track.sample(t) if late is None else late
                if swinging and limb in _HANDS:
                    assert hinges is not None
                    pos = pos + swing_displacement(pos.reshape(1, 3), hinges.centre, hinges.rotation,
                                                   hinges.radius, hinges.angles, CYMBAL_AIM_REACH_M,
                                                   CYMBAL_AIM_ABOVE_M, CYMBAL_AIM_BELOW_M)[0]
                if hinges is not None and limb in _HANDS:
                    detour = self._out_from_under(limb, pos + self.target_offset[limb])
                    if detour is not None:
                        out[limb] = (detour, np.zeros(3))
                        continue
                out[limb] = (pos + self.target_offset[limb], vel)
        return out

    def _out_from_under(self, limb: str, aim: np.ndarray) -> np.ndarray | None:
        """Where hand ``limb``'s bead goes instead of ``aim`` (3,) m while its stick gets out from under a cymbal's
        plate (None: it aims at ``aim``), metres.

        The stick as the last update saw it (``_STICK_SAMPLES`` of wrist to bead) is judged in each plate's frame
        as it is turned now (:func:`stick_under_plate`). A stick with a point under a plate (within
        ``CYMBAL_UNDER_MARGIN_M`` beyond the rim) that its target would bring within ``CYMBAL_UNDER_CLEAR_M`` of
        the plate (the stick moving as its bead) goes around the rim instead (:func:`_detour`): out toward its
        wrist, then up beside the rim to the target's height; it aims at its target again once its bead is up
        there, or once the target is that far below the plate (the plan went elsewhere)."""
        hinges = self.kit_bodies.cymbal_hinges
        assert hinges is not None
        bead = self.body.effector_pos[LIMBS.index(limb)]
        wrist = self.body.frame_pos[_WRIST_ROW[limb]]
        c = self._around.get(limb)
        if c is None:
            sides = self._plate_side.get(limb)
            if sides is None:
                sides = self._plate_side[limb] = np.zeros(len(hinges.radius), dtype=np.int64)
            c = stick_under_plate(bead, wrist, aim, hinges.centre, hinges.rotation, hinges.radius, hinges.angles,
                                  sides, _STICK_SAMPLES, CYMBAL_UNDER_MARGIN_M, CYMBAL_UNDER_CLEAR_M)
            if c < 0:
                return None
            self._around[limb] = c
        frame, centre = plate_frame(hinges.rotation[c], hinges.angles[c]), hinges.centre[c]
        aim_z = (frame.T @ (aim - centre))[2]
        top = max(aim_z, CYMBAL_UNDER_CLEAR_M)  # up beside the rim to the target's height
        if (frame.T @ (bead - centre))[2] > top - CYMBAL_UNDER_CLEAR_M / 2 or aim_z < -CYMBAL_UNDER_CLEAR_M:
            del self._around[limb]
            return None
        samples = wrist + _STICK_SAMPLES[:, None] * (bead - wrist)
        goal = centre + frame @ _detour((samples - centre) @ frame, frame.T @ (wrist - centre),
                                        float(hinges.radius[c]), top)
        step = goal - bead  # a step at a time: a far target would whip the stick into the rim
        length = float(np.linalg.norm(step))
        return bead + step * min(1.0, CYMBAL_UNDER_STEP_M / length) if length > 0.0 else goal

    def can_jump(self, t_from: float, t_to: float, max_move_m: float = JUMP_MAX_M,
                 max_speed_change_m_s: float = JUMP_MAX_SPEED_M_S, drop_strokes: bool = False) -> bool:
        """Whether the targets may jump from rig time ``t_from`` to a later ``t_to`` (seconds) unnoticed: no
        planned stroke of a limb (``JUMP_STROKE_BEFORE_S`` before its contact to ``JUMP_STROKE_AFTER_S`` after its
        bottom) is at either time or between, no limb's target moves more than ``max_move_m`` (metres) or changes
        velocity more than ``max_speed_change_m_s`` (m/s) at the jump nor strays more than ``max_move_m`` from where
        it is at ``t_from`` between the two (sampled every ``JUMP_SAMPLE_S``: a streamed stroke has no planned
        strike), and no joint target is queued (a live core trailing the rig clock after skipped steps jumps to it
        then: services/physics/core.py). ``drop_strokes``: only the two ends are checked, the strokes wholly
        between are dropped (a core trailing too far, ``MAX_TARGET_LAG_S``)."""
        if len(self.joint_track):
            return False
        held: list[tuple[Track, np.ndarray]] = []
        for track in self.limb_tracks.values():
            if not len(track):
                continue
            if (_in_stroke(track.strikes, t_from) or _in_stroke(track.strikes, t_to) if drop_strokes
                    else _stroke_between(track.strikes, t_from, t_to)):
                return False
            p0, v0 = track.sample(t_from)
            p1, v1 = track.sample(t_to)
            if float(np.linalg.norm(p1 - p0)) > max_move_m or float(np.linalg.norm(v1 - v0)) > max_speed_change_m_s:
                return False
            held.append((track, p0))
        # the costlier look between the ends only once every limb's ends allow the jump
        return drop_strokes or not any(_strays(track, t_from, t_to, p0, max_move_m) for track, p0 in held)

    def joint_reference(self, t: float, targets: dict[str, tuple[np.ndarray, np.ndarray]]
                        ) -> tuple[np.ndarray, np.ndarray]:
        """Joint targets for joint-space modes: the joint track, else open-loop IK of the Cartesian targets."""
        if len(self.joint_track):
            self.joint_track.prune(t - 1.0)
            return self.joint_track.sample(t)
        if not targets:
            return self.controller.rest.copy(), np.zeros(N_DOF)
        kin = self._kinematic()
        rows = [LIMBS.index(limb) for limb in LIMBS if limb in targets]
        # one damped least-squares iteration per step from the previous solution (targets move little in 1 ms)
        q = self._kin_q
        kin.set_state(q)
        eff, jac = kin.kinematics()
        j = jac[rows].reshape(3 * len(rows), -1)
        err = np.concatenate([targets[LIMBS[r]][0] - eff[r] for r in rows])
        vel = np.concatenate([targets[LIMBS[r]][1] for r in rows])
        inv = np.linalg.inv(j @ j.T + 0.02**2 * np.eye(j.shape[0]))
        post = 0.02 * (self.rest - q)
        dq = j.T @ (inv @ err) + post - j.T @ (inv @ (j @ post))
        qd = j.T @ (inv @ vel)
        active = np.any(self.body.chain_mask[rows], axis=0)
        q = np.where(active, np.clip(q + dq, self.body.lower, self.body.upper), self.controller.rest)
        qd = np.where(active, qd, 0.0)
        self._kin_q = q
        return q, qd

    def _head_posture(self, t: float) -> None:
        """Turn the head toward the plan's look-at point and nod (neck and head joints share the motion)."""
        if self.head is None:
            return
        head, offset = self.head
        target, nod = head.sample(t - offset)
        neck = self.body.position(self.body.link_index["head"])  # read by the update's Body.update()
        d = np.asarray(target) - neck
        yaw = math.atan2(-d[0], d[1])  # +z turns the face (+y) toward -x
        pitch = math.atan2(d[2], math.hypot(d[0], d[1]))  # looking down: negative
        base = self.controller.rest
        i_neck, i_head = _NECK_DOF, _HEAD_DOF
        # +x tilts an upright segment backward: looking down and nodding are -x
        base[i_neck + 2] = base[i_head + 2] = _clip(yaw / 2, -0.6, 0.6)
        base[i_neck] = _clip(pitch / 2, -0.5, 0.3)
        base[i_head] = _clip(pitch / 2 - nod, -0.5, 0.3)

    def passive_torques(self, q: np.ndarray | None = None, qd: np.ndarray | None = None) -> np.ndarray:
        """Fulcrum spring-damper torques (fingers), N m, for [left x, left z, right x, right z], at the fulcrum
        angles ``q`` (rad) and velocities ``qd`` (rad/s) (default: read them)."""
        if q is None or qd is None:
            q, qd = self.body.passive_state()
        if self._finger_gains is None:
            k = []
            for side in ("left", "right"):
                g = grip_for(self.grip[side], side, self.kit.handedness)
                k += [g.k_pitch, g.k_yaw]
            ks = np.array(k)
            self._finger_gains = (ks, 2 * FINGER_DAMPING_RATIO * np.sqrt(ks * FINGER_INERTIA_KGM2))
        ks, kd = self._finger_gains
        return -ks * q - kd * qd

    def _read_state(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The body's joint state at the start of the step (:meth:`Body.full_state`), also handed to the contact
        tracker for approach velocities."""
        theta, theta_dot, pq, pqd = self.body.full_state()
        trunk = self.body.parts[0]  # the legs carry no striker: the tracker needs the trunk's velocities only
        self.tracker.provide_joint_velocities(trunk.id, trunk.state_joints, self.body.trunk_velocities())
        return theta, theta_dot, pq, pqd

    def pre_step(self, t_next: float) -> None:
        """Compute and apply this step's torques for the state at the start of the step ending at ``t_next``.

        A full control update (targets, IK, inverse dynamics, limits) every ``control_every`` steps; the steps
        between keep its torques with the PD's correction for the state (:meth:`Controller.apply_between`),
        the fingers' springs and the kit's springs at every step.
        """
        sticks_touching = frozenset(self.tracker.touching)
        for striker, instrument in self.tracker.touching_instruments:
            limb = self._striker_limbs.get(striker)
            if limb is not None:
                self._last_touch[limb][instrument] = t_next
        if self._steps_to_update > 0 and self.controller.can_hold() and sticks_touching == self._touching_at_update:
            self._steps_to_update -= 1
            theta, theta_dot, pq, pqd = self._read_state()
            self.controller.apply_between(theta, theta_dot, t_next - self._last_update_s,
                                          self.passive_torques(pq, pqd))
            self.kit_bodies.pre_step(self.world)
            return
        self._steps_to_update = self.control_every - 1
        self._last_update_s = t_next
        self._touching_at_update = sticks_touching  # a stick touching or leaving a surface: update at once
        theta, theta_dot, pq, pqd = self._read_state()
        self.body.update(theta)
        sticks = self.tracker.touching
        touching = {hand for hand, stick in _HAND_STICKS if stick in sticks}
        targets = self.cartesian_targets(t_next)
        pedals = self._beater_pedal_bodies
        for limb, foot in self._feet:  # a foot resting on a footboard: no wind-up either
            if limb in targets and targets[limb][1][2] < -FOOT_STROKE_SPEED:
                continue  # a pedal stroke: the foot drives the footboard down (its end stop and the beater stop it)
            if any(((cp[1], cp[3]) == foot and cp[2] in pedals) or ((cp[2], cp[4]) == foot and cp[1] in pedals)
                   for cp in self.tracker.last_points):  # the last step's contact points, as the tracker read them
                touching.add(limb)
        self.controller.touching = touching
        self.last_targets = targets
        if len(self.posture_track):
            self.posture_track.prune(t_next - 1.0)
            posture, rate = self.posture_track.sample(t_next)
            self.controller.rest, self.controller.posture_rate = posture, rate
        self._head_posture(t_next)
        if self.controller.mode.startswith("cartesian") and not len(self.joint_track):
            theta_t, theta_dot_t = self.controller.ik_targets(theta, targets, touching)
        else:
            theta_t, theta_dot_t = self.joint_reference(t_next, targets)
        self.last_joint_target = (theta_t, theta_dot_t)
        self.controller.apply(theta, theta_dot, theta_t, theta_dot_t, self.passive_torques(pq, pqd), (pq, pqd))
        self.kit_bodies.pre_step(self.world)


def _clip(x: float, low: float, high: float) -> float:
    """``x`` within [low, high] (``np.clip``'s value for one float, without its per-call cost)."""
    return min(max(x, low), high)


def _in_stroke(strikes: list[Strike], t: float) -> bool:
    """Whether rig time ``t`` (s) is within a planned stroke of ``strikes`` (sorted by time): from
    ``JUMP_STROKE_BEFORE_S`` before its contact to ``JUMP_STROKE_AFTER_S`` after its bottom."""
    k = bisect.bisect_left(strikes, t - JUMP_STROKE_AFTER_S, key=lambda s: s.bottom)
    return k < len(strikes) and strikes[k].time - JUMP_STROKE_BEFORE_S <= t


def _stroke_between(strikes: list[Strike], t_from: float, t_to: float) -> bool:
    """Whether a planned stroke of ``strikes`` (sorted by time) is at rig time ``t_from`` or ``t_to`` (s) or
    between: its span from ``JUMP_STROKE_BEFORE_S`` before its contact to ``JUMP_STROKE_AFTER_S`` after its bottom
    meets ``[t_from, t_to]``."""
    k = bisect.bisect_left(strikes, t_from - JUMP_STROKE_AFTER_S, key=lambda s: s.bottom)
    return k < len(strikes) and strikes[k].time - JUMP_STROKE_BEFORE_S <= t_to


def _strays(track: Track, t_from: float, t_to: float, p0: np.ndarray, max_move_m: float) -> bool:
    """Whether ``track``'s target strays more than ``max_move_m`` (m) from ``p0`` (its position at ``t_from``)
    between rig times ``t_from`` and ``t_to`` (s): sampled every :data:`JUMP_SAMPLE_S` and at every knot between
    (the ends are the caller's), in one compiled loop (NumPy's calls made ``can_jump`` 4.5 times slower)."""
    times, values, velocities = track.knots(t_from, t_to)
    if len(times) < 2:  # one knot: held
        return False
    return hermite_stray(times, values, velocities, t_from, t_to, JUMP_SAMPLE_S, p0) > max_move_m


def _lead_in_apex(t0: float, p0: np.ndarray, t1: float, p1: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """The middle knot of a hand's move from ``p0`` at ``t0`` to ``p1`` at ``t1`` (seconds, metres): halfway across,
    ``LEAD_IN_RISE_M`` above the higher end, moving across at the mean speed (m/s) and not vertically."""
    across = (p1 - p0) / (t1 - t0)
    across[2] = 0.0
    apex = 0.5 * (p0 + p1)
    apex[2] = max(p0[2], p1[2]) + LEAD_IN_RISE_M
    return 0.5 * (t0 + t1), apex, across


def plate_frame(rotation: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """A cymbal's plate frame as it swings now (3, 3): its rest frame ``rotation`` (3, 3) turned by
    ``Rx(angles[0]) Ry(angles[1])`` (rad) in that frame (as :func:`kernels.swing_displacement`)."""
    ca, sa, cb, sb = math.cos(angles[0]), math.sin(angles[0]), math.cos(angles[1]), math.sin(angles[1])
    return rotation @ np.array([[1.0, 0.0, 0.0], [0.0, ca, -sa], [0.0, sa, ca]]) \
        @ np.array([[cb, 0.0, sb], [0.0, 1.0, 0.0], [-sb, 0.0, cb]])


def _detour(stick: np.ndarray, wrist: np.ndarray, radius_m: float, top_m: float) -> np.ndarray:
    """Where a stick's bead under a plate, or beside its rim, goes next, in the plate's frame (metres): ``stick``
    (S, 3) its points, the bead first, ``wrist`` (3,) its wrist, the plate in z = 0 within ``radius_m``. Under the
    plate: out toward the wrist until every point below the plate's plane is ``CYMBAL_UNDER_CLEAR_M`` beyond the
    rim, that far below the plate; beside the rim: up, to ``top_m`` above its plane."""
    out = np.array([wrist[0], wrist[1]])
    norm = math.hypot(out[0], out[1])
    out = out / norm if norm > 1e-6 else np.array([0.0, -1.0])
    clear = radius_m + CYMBAL_UNDER_CLEAR_M
    shift = 0.0
    for p in stick:
        if p[2] < 0.0 and math.hypot(p[0], p[1]) < clear:
            along = p[0] * out[0] + p[1] * out[1]  # |p + t out| = clear
            shift = max(shift, -along + math.sqrt(max(along**2 - p[0]**2 - p[1]**2 + clear**2, 0.0)))
    bead = stick[0].copy()
    if shift > 0.0:
        bead[:2] += (shift + CYMBAL_UNDER_MARGIN_M) * out
        bead[2] = min(bead[2], -CYMBAL_UNDER_CLEAR_M)
    else:
        bead[2] = top_m
    return bead


def _scales(values: np.ndarray) -> str:
    """A group's gain scales for a log line: the one value, or their range if the group's DOF differ."""
    low, high = float(values.min()), float(values.max())
    return f"{low:g}" if low == high else f"{low:g}-{high:g}"


_HAND_STICKS = (("left_hand", "left_stick"), ("right_hand", "right_stick"))
_HANDS = tuple(hand for hand, _ in _HAND_STICKS)
_NECK_DOF, _HEAD_DOF = JOINTS.index("neck") * 3, JOINTS.index("head") * 3
"""The first (x) DOF of the neck and of the head in the 57."""
_WRIST_ROW = {hand: JOINTS.index(f"{hand.split('_')[0]}_wrist") for hand in _HANDS}
"""Each hand's wrist's row in :attr:`Body.frame_pos`."""


def _box_clamp(body: Body) -> Any:
    def clamp(q: np.ndarray) -> np.ndarray:
        return np.clip(q, body.lower, body.upper)

    return clamp
