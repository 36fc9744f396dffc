"""A deterministic synthetic drummer: a stick figure playing a groove on the kit.

Lets the page, the exports, the video and the tests run without the physics
service. The figure has rigid links (constant offsets between a link frame
and its parent's), link frames at the joints, each frame's +z along the bone
to its child (sticks along +y, as in the physics model), so its world poses
are exactly what a rigid articulated body publishes. Link names follow the convention the view understands
(:mod:`services.graphics.skeleton`): ``pelvis abdomen chest neck head`` and
per side ``upper_arm forearm hand stick stick_tip thigh shin foot toe``.

Arms and legs reach their targets with analytic two-bone IK; the stick tip
lands on the kit's hit point of each stroke at the stroke's time, and an
:class:`~common.messages.Impact` is produced for it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from common.kit import EventType, Kit, load_kit
from common.messages import Impact
from services.graphics.sequence import PoseSequence

SIDES = ("left", "right")
TRUNK = ("pelvis", "abdomen", "chest", "neck", "head")
LIMB_PARTS = ("upper_arm", "forearm", "hand", "stick", "stick_tip", "thigh", "shin", "foot", "toe")
LINK_NAMES: list[str] = list(TRUNK) + [f"{s}_{p}" for s in SIDES for p in LIMB_PARTS]

# segment lengths, metres
PELVIS_HEIGHT = 0.60
ABDOMEN = 0.12
CHEST = 0.20
NECK = 0.24
HEAD = 0.08
SHOULDER_OFFSET = (0.19, 0.02, 0.20)  # in the chest frame (x: +right for the right side)
HIP_OFFSET = (0.10, 0.02, -0.04)  # in the pelvis frame
UPPER_ARM = 0.30
FOREARM = 0.27
GRIP = 0.04  # wrist -> grip point along the stick
STICK = 0.36  # grip -> tip
THIGH = 0.44
SHIN = 0.44
FOOT = 0.15  # ankle -> ball of the foot
STICK_FRAME = Rotation.from_euler("x", 90, degrees=True).as_matrix()  # hand frame (+z along the stick) -> stick (+y)


def _unit(v: np.ndarray) -> np.ndarray:
    n = float(np.linalg.norm(v))
    return v / n if n > 1e-12 else np.array([0.0, 0.0, 1.0])


def frame_from_z(z: np.ndarray, x_hint: np.ndarray) -> np.ndarray:
    """Rotation matrix (3, 3) whose +z is ``z`` and +x is as close to ``x_hint`` as possible."""
    z = _unit(z)
    x = x_hint - np.dot(x_hint, z) * z
    if np.linalg.norm(x) < 1e-9:
        x = np.cross(np.array([0.0, 1.0, 0.0]), z)
    x = _unit(x)
    y = np.cross(z, x)
    return np.column_stack([x, y, z])


def two_bone_ik(root: np.ndarray, target: np.ndarray, l1: float, l2: float, pole: np.ndarray) -> np.ndarray:
    """Middle joint position (3,) of a two-bone chain reaching ``target``, bending towards ``pole``.

    An unreachable target is approached along the line root -> target.
    """
    d = target - root
    dist = float(np.clip(np.linalg.norm(d), 1e-6, l1 + l2 - 1e-6))
    axis = _unit(d)
    a = (l1 * l1 - l2 * l2 + dist * dist) / (2 * dist)
    h = math.sqrt(max(l1 * l1 - a * a, 0.0))
    bend = pole - np.dot(pole, axis) * axis
    bend = _unit(bend) if np.linalg.norm(bend) > 1e-9 else _unit(np.cross(axis, [1.0, 0.0, 0.0]))
    return root + axis * a + bend * h


def hit_point(kit: Kit, event: EventType) -> tuple[np.ndarray, np.ndarray]:
    """World hit point (3,) metres and surface normal (3,) of an event type on ``kit``."""
    spec = kit.events[event]
    obj = kit.object(spec.object)
    rot = Rotation.from_euler("xyz", obj.rotation_deg, degrees=True)
    local = np.array([spec.r * obj.radius * math.cos(spec.theta), spec.r * obj.radius * math.sin(spec.theta), 0.0])
    return np.asarray(obj.position) + rot.apply(local), rot.apply([0.0, 0.0, 1.0])


@dataclass(frozen=True)
class Stroke:
    """One planned strike of a limb: time (s), event type, strike velocity (m/s)."""

    time: float
    event: EventType
    velocity: float


def default_groove(duration: float, tempo_bpm: float = 120.0, bass_foot: str = "right_foot") -> dict[str, list[Stroke]]:
    """A rock groove: hi-hat eighths (right hand), snare on 2 and 4 (left hand), kick on 1 and 3 (``bass_foot``:
    the kit's BASS ``preferred``, see :func:`pedal_feet`).

    The hi-hat foot stays down except on the last eighth of every bar (an open hat).
    Returns per-limb strokes ``{"right_hand": [...], "left_hand": [...], bass_foot: [...]}``.
    """
    beat = 60.0 / tempo_bpm
    strokes: dict[str, list[Stroke]] = {"right_hand": [], "left_hand": [], bass_foot: []}
    t0 = 0.5
    eighth = 0
    while t0 + eighth * beat / 2 <= duration - 0.25:
        t = t0 + eighth * beat / 2
        pos = eighth % 8
        ev = EventType.HIHATOPEN if pos == 7 else EventType.HIHATCLOSED
        if eighth % 16 == 0:
            ev = EventType.CRASH
        strokes["right_hand"].append(Stroke(t, ev, 3.0 if pos % 2 == 0 else 2.0))
        if pos in (2, 6):
            strokes["left_hand"].append(Stroke(t, EventType.SNARE, 4.0))
        if pos in (0, 4, 5):
            strokes[bass_foot].append(Stroke(t, EventType.BASS, 2.5))
        eighth += 1
    return strokes


def pedal_feet(kit: Kit) -> tuple[str, str]:
    """(the foot on the kick's pedal, the foot on the hi-hat's): BASS's and HIHATPEDAL's ``preferred`` (a
    left-handed kit's left foot kicks, as physics plays it), by default right and left; the hi-hat's is the other
    foot when both name the same."""
    def foot(event: EventType, default: str) -> str:
        spec = kit.events.get(event)
        return spec.preferred.value if spec is not None and spec.preferred.value.endswith("_foot") else default

    bass = foot(EventType.BASS, "right_foot")
    hihat = foot(EventType.HIHATPEDAL, "left_foot" if bass == "right_foot" else "right_foot")
    if hihat == bass:
        hihat = "left_foot" if bass == "right_foot" else "right_foot"
    return bass, hihat


def _stroke_profile(strokes: list[Stroke], t: float, h_up: float, h_rest: float) -> tuple[int, int, float]:
    """Between which strokes ``t`` falls and the effector height above the surface (metres)."""
    times = [s.time for s in strokes]
    j = int(np.searchsorted(times, t, side="right"))
    if j == 0:  # before the first stroke: lift from rest into it
        gap = 0.5
        u = 1.0 - min(max((times[0] - t) / gap, 0.0), 1.0) if times else 0.0
        return 0, 0, h_rest + (h_up - h_rest) * math.sin(math.pi * (0.5 + 0.5 * u)) if times else h_rest
    if j >= len(times):
        since = t - times[-1]
        return j - 1, j - 1, h_rest * min(since / 0.15, 1.0)
    t_a, t_b = times[j - 1], times[j]
    u = (t - t_a) / (t_b - t_a)
    height = h_up * min(1.0, (t_b - t_a) / 0.5) * math.sin(math.pi * u) ** 0.8
    return j - 1, j, height


class SyntheticDrummer:
    """Poses and impacts of the stick figure playing ``strokes`` on ``kit``. Deterministic."""

    def __init__(self, kit: Kit | None = None, strokes: dict[str, list[Stroke]] | None = None,
                 duration: float = 4.0, tempo_bpm: float = 120.0) -> None:
        self.kit = kit or load_kit("default")
        self.duration = duration
        self.tempo_bpm = tempo_bpm
        self.bass_foot, self.hihat_foot = pedal_feet(self.kit)
        self.strokes = strokes if strokes is not None else default_groove(duration, tempo_bpm, self.bass_foot)
        for limb in self.strokes.values():
            limb.sort(key=lambda s: s.time)

    # --- public -----------------------------------------------------------------------------
    def sequence(self, rate_hz: float = 60.0) -> PoseSequence:
        """The pose sequence from 0 to ``duration`` seconds at ``rate_hz``."""
        count = int(math.floor(self.duration * rate_hz + 1e-9)) + 1
        times = np.arange(count) / rate_hz
        return PoseSequence(list(LINK_NAMES), times, np.stack([self.pose(float(t)) for t in times]))

    def impacts(self) -> list[Impact]:
        """One impact per stroke, in time order, with the kit's hit point (r, theta, zone)."""
        out: list[tuple[float, str, Stroke]] = []
        for limb, strokes in self.strokes.items():
            for s in strokes:
                out.append((s.time, limb, s))
        out.sort(key=lambda item: (item[0], item[1]))
        impacts = []
        for seq, (t, limb, s) in enumerate(out):
            spec = self.kit.events[s.event]
            part = f"{limb.split('_')[0]}_stick_tip" if limb.endswith("hand") else f"{limb.split('_')[0]}_toe"
            impacts.append(
                Impact(seq=seq, time=t, instrument=spec.object, zone=spec.zone, r=spec.r,
                       theta=max(-7.0, min(7.0, spec.theta)), velocity=s.velocity, impulse=0.02 * s.velocity,
                       peak_force=150.0 * s.velocity, duration=0.004, part=part)
            )
        return impacts

    def pose(self, t: float) -> np.ndarray:
        """World poses (L, 7) of every link at time ``t`` seconds."""
        beat = 60.0 / self.tempo_bpm
        phase = 2 * math.pi * t / beat
        goals = {f"{side}_hand": self._hand_goal(side, t) for side in SIDES}
        goals.update({f"{side}_foot": goal for side in SIDES if (goal := self._foot_goal(side, t)) is not None})
        nod = 8.0 * (0.5 + 0.5 * math.cos(phase)) ** 4  # a nod on every beat
        return figure_pose(goals, nod_deg=nod, sway_deg=3.0 * math.sin(phase / 4))

    def _hand_goal(self, side: str, t: float) -> LimbGoal:
        strokes = self.strokes.get(f"{side}_hand", [])
        if not strokes:
            target, normal = hit_point(self.kit, EventType.SNARE if side == "left" else EventType.HIHATCLOSED)
            return LimbGoal(target, normal, 0.12)
        i, j, height = _stroke_profile(strokes, t, h_up=0.28, h_rest=0.12)
        t_a, t_b = strokes[i].time, strokes[j].time
        u = 0.0 if t_b <= t_a else min(max((t - t_a) / (t_b - t_a), 0.0), 1.0)
        u = 0.5 - 0.5 * math.cos(math.pi * u)
        pa, na = hit_point(self.kit, strokes[i].event)
        pb, nb = hit_point(self.kit, strokes[j].event)
        return LimbGoal(pa + (pb - pa) * u, _unit(na + (nb - na) * u), height)

    def _foot_goal(self, side: str, t: float) -> LimbGoal | None:
        """BASS's foot on the kick's pedal, HIHATPEDAL's on the hi-hat's (:func:`pedal_feet`; the pedals found by
        the kit's events, whatever their ids: BASS's and HIHATPEDAL's ``pedal``); None (the foot rests) when the
        kit has no such pedal. Until 7 Dec the right foot kicked on every kit, a left-handed one's too."""
        limb = f"{side}_foot"
        kicks = limb == self.bass_foot
        pedal_id = self.kit.kick_pedal() if kicks else self.kit.hihat_pedal() if limb == self.hihat_foot else None
        if pedal_id is None:
            return None
        pedal = np.asarray(self.kit.object(pedal_id).position)  # the kit checks its events' pedals exist
        if kicks:
            strokes = self.strokes.get(limb, [])
            lift = _stroke_profile(strokes, t, h_up=0.07, h_rest=0.02)[2] if strokes else 0.02
        else:
            beat = 60.0 / self.tempo_bpm
            bar_pos = (t - 0.5) % (4 * beat)
            open_from = 3.5 * beat - 0.08  # lift the foot for the open hat on the last eighth
            lift = 0.05 if open_from <= bar_pos <= 4 * beat - 0.02 else 0.0
        return LimbGoal(pedal + FOOTBOARD, np.array([0.0, 0.0, 1.0]), lift)


@dataclass(frozen=True)
class LimbGoal:
    """Where a limb's effector is: ``target + normal * height``.

    For a hand the effector is the stick tip, ``target`` a point on the struck
    surface, ``normal`` its unit normal and ``height`` (metres) how far the tip
    is above it (the stick tilts up with it, the wrist takes a third). For a
    foot the effector is the ball of the foot, ``target`` the pressed footboard,
    ``height`` the lift (the heel rises with it).
    """

    target: np.ndarray
    normal: np.ndarray
    height: float


FOOTBOARD = np.array([0.0, 0.12, 0.05])
"""Ball of the foot on a pressed pedal, relative to the pedal object's position, metres."""


def figure_pose(goals: dict[str, LimbGoal], nod_deg: float = 0.0, sway_deg: float = 0.0) -> np.ndarray:
    """World poses (L, 7) of the stick figure reaching ``goals`` (keys ``left_hand``... ``right_foot``).

    The trunk sits on the throne, leaning slightly forward, swaying ``sway_deg``
    sideways; the head nods ``nod_deg`` (chin down). Limbs missing from ``goals``
    rest (hands over the snare and hi-hat, feet on their pedals' default place).
    """
    mats: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    pelvis_p = np.array([0.0, 0.0, PELVIS_HEIGHT])
    pelvis_r = np.eye(3)
    mats["pelvis"] = (pelvis_p, pelvis_r)
    abd_r = Rotation.from_euler("yx", [sway_deg, 4.0], degrees=True).as_matrix()
    abd_p = pelvis_p + pelvis_r @ np.array([0.0, 0.0, ABDOMEN])
    mats["abdomen"] = (abd_p, abd_r)
    chest_r = abd_r @ Rotation.from_euler("x", 6.0, degrees=True).as_matrix()
    chest_p = abd_p + abd_r @ np.array([0.0, 0.0, CHEST])
    mats["chest"] = (chest_p, chest_r)
    neck_p = chest_p + chest_r @ np.array([0.0, 0.0, NECK])
    mats["neck"] = (neck_p, chest_r)
    head_r = chest_r @ Rotation.from_euler("x", nod_deg, degrees=True).as_matrix()
    mats["head"] = (neck_p + chest_r @ np.array([0.0, 0.0, HEAD]), head_r)
    rest = {
        "left_hand": LimbGoal(np.array([-0.08, 0.42, 0.65]), np.array([0.0, 0.0, 1.0]), 0.12),
        "right_hand": LimbGoal(np.array([-0.31, 0.42, 0.92]), np.array([0.0, 0.0, 1.0]), 0.12),
        "left_foot": LimbGoal(np.array([-0.38, 0.40, 0.07]), np.array([0.0, 0.0, 1.0]), 0.0),
        "right_foot": LimbGoal(np.array([0.05, 0.42, 0.07]), np.array([0.0, 0.0, 1.0]), 0.02),
    }
    for side in SIDES:
        sign = 1.0 if side == "right" else -1.0
        shoulder = chest_p + chest_r @ np.array([sign * SHOULDER_OFFSET[0], *SHOULDER_OFFSET[1:]])
        _arm(mats, side, sign, shoulder, goals.get(f"{side}_hand", rest[f"{side}_hand"]))
        hip = pelvis_p + pelvis_r @ np.array([sign * HIP_OFFSET[0], *HIP_OFFSET[1:]])
        _leg(mats, side, sign, hip, goals.get(f"{side}_foot", rest[f"{side}_foot"]))
    out = np.zeros((len(LINK_NAMES), 7))
    for i, name in enumerate(LINK_NAMES):
        p, r = mats[name]
        out[i, :3] = p
        out[i, 3:] = Rotation.from_matrix(r).as_quat()
    return out


def _arm(mats: dict[str, tuple[np.ndarray, np.ndarray]], side: str, sign: float, shoulder: np.ndarray,
         goal: LimbGoal) -> None:
    target, normal, height = np.asarray(goal.target, float), _unit(np.asarray(goal.normal, float)), goal.height
    horizontal = target - shoulder
    horizontal[2] = 0.0
    d0 = _unit(_unit(horizontal) + np.array([0.0, 0.0, -0.35]))
    tip = target + normal * height
    wrist = target - (GRIP + STICK) * d0 + normal * (0.35 * height)
    direction = _unit(tip - wrist)
    wrist = tip - (GRIP + STICK) * direction  # the stick ends exactly at the tip goal
    elbow = two_bone_ik(shoulder, wrist, UPPER_ARM, FOREARM, np.array([sign * 1.0, -0.4, -1.0]))
    wrist = elbow + _unit(wrist - elbow) * FOREARM
    side_axis = np.array([sign, 0.0, 0.0])
    mats[f"{side}_upper_arm"] = (shoulder, frame_from_z(elbow - shoulder, side_axis))
    mats[f"{side}_forearm"] = (elbow, frame_from_z(wrist - elbow, side_axis))
    hand_r = frame_from_z(direction, np.array([0.0, 0.0, 1.0]) if abs(direction[2]) < 0.9 else side_axis)
    mats[f"{side}_hand"] = (wrist, hand_r)
    grip = wrist + direction * GRIP
    stick_r = hand_r @ STICK_FRAME  # the stick along its link's +y, as physics has it (services/physics/sticks.py)
    mats[f"{side}_stick"] = (grip, stick_r)
    mats[f"{side}_stick_tip"] = (grip + direction * STICK, stick_r)


def _leg(mats: dict[str, tuple[np.ndarray, np.ndarray]], side: str, sign: float, hip: np.ndarray,
         goal: LimbGoal) -> None:
    lift = max(0.0, goal.height)
    ball = np.asarray(goal.target, float) + np.array([0.0, 0.0, lift])
    angle = math.radians(28.0 + 160.0 * min(lift, 0.2))
    ankle = ball + FOOT * np.array([0.0, -math.cos(angle), math.sin(angle)])
    knee = two_bone_ik(hip, ankle, THIGH, SHIN, np.array([sign * 0.2, 1.0, 0.8]))
    ankle = knee + _unit(ankle - knee) * SHIN
    ball = ankle + _unit(ball - ankle) * FOOT
    side_axis = np.array([1.0, 0.0, 0.0])
    mats[f"{side}_thigh"] = (hip, frame_from_z(knee - hip, side_axis))
    mats[f"{side}_shin"] = (knee, frame_from_z(ankle - knee, side_axis))
    foot_r = frame_from_z(ball - ankle, side_axis)
    mats[f"{side}_foot"] = (ankle, foot_r)
    mats[f"{side}_toe"] = (ball, foot_r)


def synthetic_performance(duration: float = 4.0, rate_hz: float = 60.0,
                          kit: Kit | None = None) -> tuple[PoseSequence, list[Impact]]:
    """Pose sequence and impacts of the default groove, ``duration`` seconds at ``rate_hz``."""
    drummer = SyntheticDrummer(kit=kit, duration=duration)
    return drummer.sequence(rate_hz), drummer.impacts()
