"""The 2001 paper's kinematic keyframe mode: a baseline that needs no physics.

Each stroke is three key frames (Kragtwijk, Nijholt and Zwiers 2001): *before*
(``delta`` = 100 ms earlier, the tip raised along the surface normal by a
height that follows the velocity), *contact* (at the hit point) and *after*
(``delta`` later, raised by the before height times the object's elasticity).
Overlap rules: when a stroke's *after* frame would come later than the same
limb's next *before* frame, or less than ``delta / 2`` before it (inter-onset
interval under ``2.5 * delta``), both are
replaced by one frame halfway between the contacts, at the lower of the two
heights scaled by ``interval / (2 * delta)``. Key frames are joined by cubic
Hermite curves (velocities from neighbouring frames; at a contact the
approach velocity), so the baseline is also continuous in position and
velocity.

Key poses (the 2001 paper's UP and DOWN poses, saved by the graphics pose
editor in ``poses.yaml``, :mod:`common.gesture.keyposes`): when the poses
``EVENT.limb.UP`` and ``EVENT.limb.DOWN`` exist, the *before* and *after*
frames of that limb's strokes on that event are raised along the saved
DOWN -> UP move of the effector instead of the surface normal; the UP pose is
the preparation of a full-velocity stroke, so the raise is that move scaled by
``height(velocity) / height(1)``. Without a file or a pose the shipped default
(the surface normal) applies, so ``plan_keyframes`` without poses is unchanged.

Cymbals swing after a stroke as ``eta ** t * alpha_max * sin(beta * t)``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from common.gesture.heights import foot_height, stick_height
from common.gesture.keyposes import KeyPoses
from common.gesture.plan import CymbalSwing, GesturePlan, LimbTrajectory, PlannedStroke
from common.gesture.planner import PlannerConfig, _head, _rest_event
from common.kit import Kit, Limb
from common.score.events import Score
from common.score.limbs import HANDS, Assignment

DELTA = 0.100
"""Seconds between a stroke's before/contact/after key frames."""
SWING_ETA = 0.05
"""Cymbal swing decay base: the amplitude falls to eta after one second."""
SWING_BETA = 2 * np.pi * 1.2
"""Cymbal swing angular frequency, rad/s (about 1.2 Hz)."""
SWING_ALPHA = 0.20
"""Cymbal swing amplitude at full velocity, radians."""


def plan_keyframes(
    assignment: Assignment,
    kit: Kit,
    score: Score | None = None,
    delta: float = DELTA,
    lead_in: float = 1.0,
    tail: float = 1.0,
    poses: KeyPoses | Path | str | None = None,
) -> GesturePlan:
    """Key-frame plan (mode ``"keyframe"``) of an assignment; see the module docstring.

    ``poses``: the editor's key poses (a :class:`KeyPoses` or the path of a ``poses.yaml``; a missing file
    means the defaults). Raises ``ValueError`` for an invalid poses file.
    """
    keys = poses if isinstance(poses, KeyPoses) else KeyPoses.load(poses)
    notes = assignment.notes
    first = notes[0].time if notes else 0.0
    last = notes[-1].time if notes else 0.0
    start, end = first - lead_in, last + tail
    trajectories: dict[Limb, LimbTrajectory] = {}
    strokes: list[PlannedStroke] = []
    swings: list[CymbalSwing] = []
    for limb in Limb:
        mine = [n for n in notes if n.limb == limb]
        hand = limb in HANDS
        frames: list[tuple[float, np.ndarray, str]] = []  # time, position, kind
        info = []
        for n in mine:
            target, normal = (np.array(v) for v in kit.effector_target(n.event, limb, n.pitch))
            obj = kit.object_for(n.event, n.pitch)
            h = stick_height(n.velocity) if hand else foot_height(n.velocity)
            up = normal  # the direction the effector is raised along (unit)
            lift = keys.lift(n.event, limb)
            if lift is not None:  # the saved UP/DOWN poses: their move, scaled from a full-velocity stroke
                full = stick_height(1.0) if hand else foot_height(1.0)
                size = float(np.linalg.norm(lift))
                up, h = lift / size, size * h / full
            info.append((n, target, normal, up, h, obj))
        for k, (n, target, normal, up, h, obj) in enumerate(info):
            before = (n.time - delta, target + h * up, "before")
            if k > 0:
                pn, pt, _, pnorm, ph, pobj = info[k - 1]
                interval = n.time - pn.time
                if interval < 2.5 * delta:  # overlap (or nearly): one frame halfway
                    frames.pop()  # the previous stroke's after frame
                    scale = min(1.0, interval / (2 * delta))
                    height = min(ph * pobj.elasticity, h) * scale
                    both = pnorm + up
                    normal_mid = both / np.linalg.norm(both) if np.linalg.norm(both) > 1e-6 else up
                    before = ((pn.time + n.time) / 2, (pt + target) / 2 + height * normal_mid, "mid")
            frames.append(before)
            frames.append((n.time, target, "contact"))
            frames.append((n.time + delta, target + h * obj.elasticity * up, "after"))
            speed = h / delta
            hit = target if limb in HANDS else np.array(kit.hit_point(n.event, n.pitch)[0])  # a hand's own point
            struck_r, struck_theta = kit.struck_point(n.event, limb)
            strokes.append(
                PlannedStroke(
                    time=n.time,
                    limb=limb,
                    event=n.event,
                    object_id=obj.id,
                    hit_point=hit,
                    target=target,
                    normal=normal,
                    velocity=speed,
                    note_velocity=n.velocity,
                    note_index=n.index,
                    zone=kit.spec(n.event).zone,
                    r=struck_r,
                    theta=struck_theta,
                    lift=h,
                    rebound_velocity=speed * obj.elasticity,
                    contact_duration=0.0,
                )
            )
            if obj.kind == "cymbal":
                horizontal = np.cross(normal, [0.0, 0.0, 1.0])
                axis = (
                    horizontal / np.linalg.norm(horizontal)
                    if np.linalg.norm(horizontal) > 1e-6
                    else np.array([1.0, 0, 0])
                )
                swings.append(CymbalSwing(obj.id, n.time, SWING_ALPHA * n.velocity, SWING_ETA, SWING_BETA, axis))
        if not frames:
            ev = _rest_event(kit, limb)
            if ev is None:
                continue
            tgt, nrm = (np.array(v) for v in kit.effector_target(ev, limb))
            rest = tgt + (0.1 if hand else 0.01) * nrm
            trajectories[limb] = LimbTrajectory(limb, np.array([start, end]), np.array([rest, rest]), np.zeros((2, 3)))
            continue
        times = np.array([start] + [f[0] for f in frames] + [max(end, frames[-1][0] + 0.05)])
        pos = np.array([frames[0][1]] + [f[1] for f in frames] + [frames[-1][1]])
        keep = np.concatenate([[True], np.diff(times) > 1e-6])
        times, pos = times[keep], pos[keep]
        kinds = ["rest"] + [f[2] for f in frames] + ["rest"]
        kinds = [k for k, ok in zip(kinds, keep, strict=True) if ok]
        vel = np.zeros_like(pos)
        for i in range(1, len(times) - 1):
            if kinds[i] == "contact":
                vel[i] = (pos[i] - pos[i - 1]) / (times[i] - times[i - 1])
            elif kinds[i] == "mid":
                vel[i] = 0.0
            else:
                vel[i] = (pos[i + 1] - pos[i - 1]) / (times[i + 1] - times[i - 1]) * 0.5
        trajectories[limb] = LimbTrajectory(limb, times, pos, vel)
    strokes.sort(key=lambda s: (s.time, s.limb.value))
    plan_end = max((t.end_time for t in trajectories.values()), default=end)
    return GesturePlan(
        trajectories=trajectories,
        strokes=strokes,
        issues=list(assignment.issues),
        head=_head(strokes, score, start, plan_end, PlannerConfig()),
        start_time=start,
        end_time=plan_end,
        kit_name=kit.name,
        mode="keyframe",
        cymbal_swings=swings,
    )
