"""The gesture planner: limb assignments -> co-articulated Cartesian trajectories.

For each limb, each stroke is prepared by a gesture unit chosen by grip,
nuance (per note or global) and the local inter-onset interval (IOI). The
unit's normalised stick-tip height profile is time-warped to the IOI (slow
notes hover at the unit's apex instead of stretching it), scaled by the
stroke's preparatory height (from velocity, capped by the IOI) and laid along
the surface normal over a minimum-jerk path between successive targets. A
cubic Hermite correction then makes each segment start exactly at the previous
contact's rebound state (elasticity x strike speed, along the normal) and end
exactly at the next contact's strike state, so trajectories are continuous in
position and velocity. Around each contact the velocity reverses over the
unit's contact time (3-6 ms).

The head looks at a smoothed mean of the hands' next hit points and nods on
the beats.
"""

from __future__ import annotations

import bisect
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from common.gesture.database import GestureDatabase, GestureUnit, default_database
from common.gesture.heights import chick_speed, foot_height, foot_speed, stick_height, stick_speed, tempo_cap
from common.gesture.plan import (
    GesturePlan,
    Grip,
    HeadTrajectory,
    LimbTrajectory,
    Nuance,
    PlannedStroke,
    hermite,
)
from common.kit import BEATER_CONTACT_PRESS, EventType, Kit, KitObject, Limb, foot_target_for_press
from common.score.events import Score
from common.score.hands import HandAlgorithm, Sticking
from common.score.limbs import FEET, HANDS, PROGRESS_EVERY, Assignment, Note, ProgressCallback, distribute

VERTICAL_SHARE = 0.6
"""Share of a segment over which a height change between targets is made (early when rising, late when falling)."""
MAX_DESCENT_SPEED = 3.0
"""A fall to a lower target is spread over more of its segment (up to all of it) so that its peak speed stays
under this, m/s: a hand coming down late from the hi-hat to the snare (28 cm in 0.17 s) was planned at 6.3 m/s,
braking to the stroke's 0.9 m/s in 40 ms, which the arm cannot follow: the stick hit the head 14 ms early at
4.2 m/s."""
MAX_DESCENT_SHARE = 0.8
"""The fall never starts in the first fifth of a segment: the stick first leaves the instrument it struck (a fall
from the first instant clipped the hi-hat's edge on the way to the snare)."""
CORRECTION_WINDOW = 0.06
"""Seconds at each end of a segment over which the boundary velocities are matched."""
REBOUND_BLEND = 0.25
"""Seconds over which the displacement of a segment's initial velocity (a rebound) is blended out."""
CLEARANCE = 0.02
"""Least lift of a stick between two strokes, metres."""
REBOUND_CLEARANCE = 0.01
"""Extra lift per m/s of the previous stroke's rebound, metres (the rebound carries the stick up)."""
MOVE_CLEARANCE = 0.3
"""Extra lift per metre of horizontal move to the next target, metres."""
HOLD_RISE = 0.08
"""Seconds in which a bass-drum foot lets its footboard back up after a stroke."""
HIHAT_CLOSE_TAIL_M = 0.03
"""An open hi-hat's pedal lift above this (metres) closes as a lift of this height did: the foot falls quickly to
the path of that fall, then follows it (a higher lift falling evenly closed the plates 40-50 ms later, half
open at the next closed note 0.25 s after the open one, and 9 cm let them meet as a pedal chick)."""
HIHAT_CLOSE_TAIL_FROM = 0.25
"""... joining that fall this far (a fraction of ``hihat_close_s``) into it, its foot 2.5 cm above rest: well before
the plates meet (at half of it)."""
HIHAT_OPEN_AFTER_S = 0.01
"""An open hi-hat's pedal rise starts at the earliest this long after the previous closed hi-hat stroke (the foot
rests 1 cm past the plates' meeting: they part well after)."""
HIHAT_OPEN_LEAD_S = 0.02
"""... and reaches its lift at the latest this long before the open note."""
HIHAT_OPEN_HOLD_S = 0.02
"""The pedal held up at least this long after the open note (the stick's contact) before the foot lets it down."""
HIHAT_MEET_FRACTION = 0.5
"""The plates meet about this far into the let-down (215 ms after the note, 0.095 s into 0.2 s)."""
HIHAT_CLOSED_BY_S = 0.02
"""... at the latest this long before the next closed hi-hat stroke."""
HIHAT_OPEN_MIN_S = 0.02
"""An open window whose rise or fall the neighbours leave shorter than this is not lifted."""
FOOT_RISE_SPEED = 0.6
"""A foot's lift above its pedal (rest height plus stroke lift) is at most this times the time since its
previous stroke, m/s. Without it a kick double 90 ms apart was planned as a 9 cm lift and fall (4.5 m/s) and
played at 10 m/s whatever its velocity; with it (10 Groove validation files, one run) the kick's velocity
ranking went from Spearman 0.29 to 0.36 and the pooled one from 0.83 to 0.86, F@25 unchanged (0.91)."""
KICK_SOFTER_RISE = 0.5
"""A bass-drum stroke softer than the one before it rises at most this share of ``FOOT_RISE_SPEED`` (when it is
half as fast or less; sliding to the full speed as it nears the previous one's): a ghost kick soon after a loud
one is a small stroke from where the footboard is (heel-toe), not the board let up almost to its rest. At the full
0.6 m/s a ghost 80-120 ms after a loud kick was a 5-6 cm rise at up to 3.4 m/s and a fall at 2 m/s braked to the
ghost's 0.44 m/s: the board stopped short of the beater's contact (the ghost sounded 18-21 ms late by following
through, or not at all), or, at 60-80 ms, met the head at 3.1-4.1 m/s, as loud as the loud kick. A louder stroke
after a softer one keeps the full rise (at half for all kicks, such doubles lost their loudness: kick Spearman
0.95 -> 0.85 on six Groove validation files; docs/gestures.md)."""
KICK_DOUBLE_DEPTH = 0.008
"""Such a softer bass-drum stroke aims this much deeper (metres) times the share of its lift it loses: after a
hard kick the same foot height presses the board less (0.91 against 0.93 of its travel at the planned bottom; the
beater meets the head at 0.95)."""
KICK_REST_GAP_S = 0.75
"""A bass-drum foot's stroke this long or more (s) after its previous one, or its first (a live plan's: this long
after the foot's last stroke played before it, ``plan_gestures``' ``last_strokes``), is made from rest: it
passes the height where the beater meets the head at the note time (:func:`kick_contact_rise`). By then the
footboard under the foot held at its rest height has settled (pressed 0.10 of its travel 0.1 s after a kick at
velocity 0.4, 0.18 from 0.7 s on) and kicks aimed at the flat board sounded as early as lone kicks from rest, by
the foot's time over that rise: at velocity 0.4 0.75 s after another 7 ms (7.3 ms), 1 s after another at 0.3, 0.7
and 1.0 9, 5 and 3 ms (120 bpm, 1.75 m; the rise takes 9.0, 4.8 and 3.5 ms). 1.5 s until 7 Dec, which left kicks
0.3-1.5 s after another 5-8 ms early on the Groove subset. Below ``CONTEXT_S`` of the score player (2 s), so a live
window's plan and the whole score's agree on every kick they splice."""
KICK_RAISE_FROM_S = 0.35
"""A stroke more than this long (s) after the foot's previous one, the board still settling, is raised by
``kick_contact_rise`` times its gap's share of the way from this to ``KICK_REST_GAP_S`` (none here, all of it
there), and falls as one from rest when its foot would brake (``KICK_REST_FALL``). Aimed at the flat board, kicks at
velocity 0.4 0.4 s after another sounded 1-2 ms early, 0.6 s after 4-5 ms (a share of 0.2 and 0.6 of the 7.3 ms
the rise takes); 0.25 s after another within 3 ms (left aimed at the flat board). docs/physics.md, "Kicks"."""
KICK_RAISE_MIN_S = 1e-5
"""A raise (``KICK_RAISE_FROM_S``) the foot passes in less than this (s, a hundredth of the physics step) is left
out: the press-on knot would all but fall on the note's."""
KICK_RAISE_ROOM_S = 0.1
"""... and only when the foot's next stroke is at least this long (s) after the raised one's press-on and contact:
a later bottom must not squeeze the approach to the next kick (at the closest kicks, 30 ms, it left none)."""
KICK_REST_FALL = 3.0
"""A bass-drum stroke from rest (:data:`KICK_REST_GAP_S`) whose foot would brake into the pedal falls from its apex
(rest height plus lift) to the pedal over this many times that height over the stroke's speed: the curve
``1 - s^3`` of :func:`foot_profile`, the foot speeding up all the way into the pedal (:func:`rest_fall_profile`).
The rest height let down on its own over ``HOLD_FALL`` under the lift's fall made a soft stroke's foot fall at
0.9-1.0 m/s and brake to its 0.4-0.9 m/s: the footboard ran ahead of the foot and the beater met the head early
(lone kicks at velocity 0.1 14 ms, 0.2 9 ms). Falling at an even speed into the pedal (1.5 times, the shortest
cubic that never brakes) still left them 11 and 7 ms early, speeding up into the pedal 7 and 4 (docs/evaluation.md,
"Kicks from rest"). Louder strokes, whose lift's fall outruns the rest let down, keep their shape
(:data:`KICK_BRAKE_TOLERANCE`)."""
KICK_BRAKE_TOLERANCE = 1e-6
"""A planned foot fall whose speed drops by more than this (m/s) between its apex and the pedal brakes."""
KICK_RUN_GAP_S = 0.091
"""A bass-drum stroke less than this long (s) after the foot's previous one, itself as soon after the one before it
(a run of fast kicks from its third kick on), meets the pedal slower (:data:`KICK_RUN_SLOWER`). With the leg's
posture held (services/physics/control.py, ``LEG_POSTURE_BAND_RAD``) the foot plays such runs from a board let up
less and the same planned stroke gave the beater more speed, the more the faster: from the run's third kick on,
against a lone kick of the same velocity (0.7: 3.67 m/s), 16ths at 190 bpm (79 ms apart) +28 %, 180 +21 %, 170
+9 %, 160 -9 %, eighths at 180 +4 %; at 180 bpm velocity 0.44 +32 %, 0.22 +52 % (physics core; docs/physics.md,
"Kicks"). A double's second kick is not louder (3.54 m/s at 0.7), so it keeps its speed."""
KICK_RUN_SLOWER = 29.0
"""... by this share of its planned speed per second its gap is short of :data:`KICK_RUN_GAP_S` (1/s; at most
:data:`KICK_RUN_SLOWER_MAX`): 16ths at 180 bpm 0.23 slower, 170 0.09. A share, not a speed: 0.39 m/s less at every
velocity left velocity 0.7 3 % over a lone kick but 0.44 15 % under it. Only the foot's fall into the pedal: its
press and let-up after the contact are planned from the stroke's own speed, so the foot leaves each contact as it
did (and a live note's window re-joins its queued plan where it did)."""
KICK_RUN_SLOWER_MAX = 0.35
"""The largest share (:data:`KICK_RUN_SLOWER`), from 79 ms apart down (16ths at 190 bpm)."""
HOLD_FALL = 0.12
"""Seconds before a stroke over which the foot's rest height blends into the stroke."""
HOLD_FALL_SHARE = 0.5
"""A bass-drum foot's rest height (the footboard let up) blends into a stroke over at most this share of the time
since the previous one (the hi-hat foot's, a third). The
beater follows the fastest part of the foot's fall, not its end: at a third (before), a kick 0.12-0.25 s after
the previous one was played 1.5-2 times as fast as the same note alone (0.2 s apart at velocity 25: 2.67 m/s
against 1.40), and the kick's velocity ranking on the Groove validation split was 0.97 for kicks 0.25 s or more
apart but 0.38-0.65 for closer ones. At half (the whole split, one run each): kick Spearman 0.61 -> 0.80, pooled
0.758 -> 0.790, F@25 0.9775 -> 0.9774; soft kicks 0.1-0.2 s after a louder one sometimes stop short of the head
(kick notes without contact 56 -> 91 of about 9,100)."""
TAIL_RISE = 0.25
"""Seconds in which a limb rises to its rest height after its last stroke (then it holds there)."""
BOUNCE_MIN_LIFT = 0.004
"""Least height of the bounce of a rebound double between its two contacts, metres."""
NOD_REACH = 28.0
"""A head nod's bump exp(-(dt / width)^2) is exactly 0.0 in float64 beyond 27.3 widths (exp underflows below
-745), so it is summed only within this many widths of its beat."""


def bounce_height(rebound: float, speed: float, flight: float, cap: float) -> float:
    """Apex (metres) of the bounce between the two notes of a rebound double.

    The tip leaves the first contact at ``rebound`` m/s and meets the head again
    ``flight`` seconds later at ``speed`` m/s; the fingers steer the stick on the
    smooth (cubic) path between, whose apex is about a quarter of the mean speed
    times the flight time. Between ``BOUNCE_MIN_LIFT`` and ``cap`` (the note's own
    preparatory height within the tempo cap).
    """
    natural = 0.25 * 0.5 * (rebound + speed) * max(flight, 0.0)
    return float(min(max(natural, BOUNCE_MIN_LIFT), max(cap, BOUNCE_MIN_LIFT)))


@dataclass(frozen=True)
class PlannerConfig:
    """Planner settings (seconds, metres)."""

    grip: Grip = Grip.GERMAN
    nuance: Nuance = Nuance.TENUTO
    lead_in: float = 1.0  # rest before the first note, seconds
    tail: float = 1.0  # after the last note, seconds
    rest_height: float = 0.10  # hands hover this far above their first/last target, metres
    # the hi-hat foot rests this far above its chick target, the footboard where the cymbals meet: below it, the
    # pedal held past the closing point clamps the hi-hat shut (between strokes too), metres
    foot_rest_height: float = -0.010
    kick_rest_height: float = 0.055  # a bass-drum foot rests on the raised footboard (beater off the head), metres
    foot_contact: float = 0.010  # footboard bottom-out time, seconds
    foot_cycle: float = (
        0.30  # a pedal stroke's lift and fall take at most this long; the foot rests on the pedal between
    )
    # the hi-hat foot lifts the pedal this much (metres) around open hi-hat notes: the plates 10.3 mm apart at the
    # stroke (default kit, 1.75 m drummer; the rest opening 15 mm), where 3 cm left them 2.7 mm apart, barely off
    # a closed hat; from 9 cm the footboard nears its stop, from 10 cm the foot leaves it (docs/physics.md)
    hihat_open_lift: float = 0.07
    # ... and lets it down again over this long (seconds): slowly enough that the plates meet below interaction's
    # slowest hi-hat chick (closing in 0.1 s, they met at 0.11-0.16 m/s: a chick the score does not have)
    hihat_close_s: float = 0.2
    knots_per_second: float = 120.0
    nod_amplitude: float = 0.08  # radians
    nod_width: float = 0.06  # seconds
    head_rate: float = 50.0  # Hz


@dataclass
class _Stroke:
    time: float
    target: np.ndarray
    normal: np.ndarray
    speed: float
    rebound: float
    lift: float
    contact: float
    nuance: Nuance
    bounce: bool = False  # the second note of a rebound double


def _min_jerk(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return s**3 * (10 - 15 * s + 6 * s**2), 30 * s**2 * (1 - s) ** 2


FOOT_FALL_SHARE = 0.6
"""A foot stroke's fall takes at most this share of its cycle (the rest is the lift)."""


def foot_profile(phi: np.ndarray, lift: float, speed: float, cycle: float) -> tuple[np.ndarray, np.ndarray]:
    """Height above the pedal (0..1 of ``lift``) and its rate per unit phase of a foot stroke over ``cycle`` s.

    The foot lifts (minimum jerk) to the apex, then falls on a cubic that leaves the apex at rest and meets the
    pedal at ``speed`` m/s: the fall takes ``3 lift / speed`` (the curve ``1 - s^3``, a foot accelerating into
    the pedal), at most ``FOOT_FALL_SHARE`` of the cycle (then faster, still monotonic). A gesture unit's
    stick profile, used before, ended at a fraction of the planned speed, and the last milliseconds' correction
    asked the foot for an acceleration it could not make: the hi-hat's plates met slowly and late or not at all.
    """
    fall = min(3.0 * lift / max(speed, 1e-6), FOOT_FALL_SHARE * cycle) / cycle  # phase units
    apex = 1.0 - fall
    up, dup = _min_jerk(np.clip(phi / max(apex, 1e-9), 0.0, 1.0))
    dup = np.where(phi < apex, dup / max(apex, 1e-9), 0.0)
    s = np.clip((phi - apex) / fall, 0.0, 1.0)
    slope = speed * fall * cycle / max(lift, 1e-9)  # the end velocity in these units (s per fall, height per lift)
    h_fall = 2 * s**3 - 3 * s**2 + 1 - slope * (s**3 - s**2)
    dh_fall = (6 * s**2 - 6 * s - slope * (3 * s**2 - 2 * s)) / fall
    falling = phi > apex
    return np.where(falling, h_fall, up), np.where(falling, dh_fall, dup)


def rest_fall_profile(phi: np.ndarray, lift: float, hold: float, speed: float, cycle: float, fall_s: float
                      ) -> tuple[np.ndarray, np.ndarray]:
    """A bass-drum foot's stroke from its rest, ``hold`` metres above the pedal line: height (metres) above that
    rest and its rate per unit phase over ``cycle`` s.

    The foot lifts ``lift`` (minimum jerk, as :func:`foot_profile`), then falls the whole ``lift + hold`` on one
    cubic that leaves the apex at rest and meets the pedal at ``speed`` m/s over ``fall_s`` (at most
    ``FOOT_FALL_SHARE`` of the cycle): over 1.5 to 3 times the height over the speed it speeds up all the way into
    the pedal (3, ``KICK_REST_FALL``: the curve ``1 - s^3``). Not the rest let down on its own (``HOLD_FALL``, to
    rest at the pedal) under the lift's fall: that fall braked into a soft stroke (at velocity 0.1 the foot came
    down at 0.93 m/s and met the pedal at 0.50) and the footboard ran ahead of the foot into the head."""
    height = lift + hold
    fall = min(fall_s, FOOT_FALL_SHARE * cycle) / cycle  # phase units
    apex = 1.0 - fall
    up, dup = _min_jerk(np.clip(phi / max(apex, 1e-9), 0.0, 1.0))
    dup = np.where(phi < apex, dup / max(apex, 1e-9), 0.0)
    s = np.clip((phi - apex) / fall, 0.0, 1.0)
    slope = speed * fall * cycle / max(height, 1e-9)  # the end speed in these units (heights per fall)
    h_fall = 2 * s**3 - 3 * s**2 + 1 - slope * (s**3 - s**2)
    dh_fall = (6 * s**2 - 6 * s - slope * (3 * s**2 - 2 * s)) / fall
    falling = phi > apex
    return (np.where(falling, height * h_fall - hold, lift * up),
            np.where(falling, height * dh_fall, lift * dup))


def _segment(
    t0: float,
    p0: np.ndarray,
    v0: np.ndarray,
    n0: np.ndarray,
    t1: float,
    p1: np.ndarray,
    v1: np.ndarray,
    n1: np.ndarray,
    lift: float,
    unit: GestureUnit | None,
    knots_per_second: float,
    cycle: float | None = None,
    hold: float = 0.0,
    hold_from_start: bool = False,
    rest_fall: float = 0.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Knots (times (K,), positions (K, 3), velocities (K, 3)) from t0 to t1 inclusive.

    ``cycle`` (feet): the unit's profile plays over the last ``cycle`` seconds only and
    the effector rests on the target line before (the foot stays on the pedal), raised by
    ``hold`` metres along the normal (a bass-drum foot lets the footboard up between strokes; the hi-hat foot,
    negative, holds its pedal past the closing point); ``hold_from_start``: the segment starts already held
    (a foot's first stroke, from its rest), else the hold rises in after the previous stroke; ``rest_fall`` (a
    bass-drum stroke from rest, seconds): the hold falls with the lift, over this long (:func:`rest_fall_profile`;
    the cycle widens to fit it), not on its own.
    """
    d = t1 - t0
    k = int(np.clip(d * knots_per_second, 4, 80))
    w = min(0.4 * d, CORRECTION_WINDOW)
    tau = np.unique(np.concatenate([np.linspace(0.0, d, k + 1), np.linspace(0.0, w, 7), np.linspace(d - w, d, 7)]))
    tau = tau[np.concatenate([[True], np.diff(tau) > 1e-6])]
    tau[-1] = d
    s = tau / d
    m, dm = _min_jerk(s)
    # over the top: rise early when the next target is higher, descend late when it is lower
    start = p0 - hold * n0 if hold_from_start else p0  # a held start: the base path runs on the pedal line
    delta = p1 - start
    horizontal = np.array([delta[0], delta[1], 0.0])
    vertical = np.array([0.0, 0.0, delta[2]])
    if delta[2] > 0:
        mz, dmz = _min_jerk(np.clip(s / VERTICAL_SHARE, 0.0, 1.0))
        dmz = np.where(s < VERTICAL_SHARE, dmz / VERTICAL_SHARE, 0.0)
    else:  # a minimum-jerk fall over ``share`` of the segment peaks at 1.875 |dz| / (share d)
        share = min(MAX_DESCENT_SHARE, max(VERTICAL_SHARE, 1.875 * -delta[2] / (d * MAX_DESCENT_SPEED)))
        mz, dmz = _min_jerk(np.clip((s - (1 - share)) / share, 0.0, 1.0))
        dmz = np.where(s > 1 - share, dmz / share, 0.0)
    base = start + np.outer(m, horizontal) + np.outer(mz, vertical)
    dbase = np.outer(dm / d, horizontal) + np.outer(dmz / d, vertical)
    merged = rest_fall > 0.0 and cycle is not None and unit is not None and lift > 0 and hold > 0.0
    if unit is not None and lift > 0:
        period = unit.period
        apex = unit.apex_phase
        if cycle is not None:
            c = min(max(cycle, rest_fall / FOOT_FALL_SHARE), d)
            phi = np.clip((tau - (d - c)) / c, 0.0, 1.0)
            dphi = np.where(tau > d - c, 1.0 / c, 0.0)
        elif d > period:
            rise, fall = period * apex, period * (1 - apex)
            phi = np.where(tau < rise, tau / period, np.where(tau > d - fall, apex + (tau - (d - fall)) / period, apex))
            dphi = np.where((tau < rise) | (tau > d - fall), 1.0 / period, 0.0)
        else:
            phi, dphi = s, np.full_like(s, 1.0 / d)
        if merged:  # from rest: the lift, then the hold and the lift fall together (metres)
            lifted, dlifted = rest_fall_profile(phi, lift, hold, max(float(-(v1 @ n1)), 0.0), c, rest_fall)
            dlifted = dlifted * dphi
        else:
            if cycle is not None:  # a foot: its own lift and fall into the pedal at the stroke's speed
                h, dh = foot_profile(phi, lift, max(float(-(v1 @ n1)), 0.0), min(cycle, d))
                dh = dh * dphi
            else:
                h = unit.profile(phi)
                dh = unit.profile(phi, 1) * dphi
            lifted, dlifted = lift * h, lift * dh
        normal = np.outer(1 - m, n0) + np.outer(m, n1)
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        base = base + normal * lifted[:, None]
        dbase = dbase + normal * dlifted[:, None]
    if hold != 0.0:
        rise, fall = min(HOLD_RISE, d / 3), min(HOLD_FALL, (HOLD_FALL_SHARE if hold > 0 else 1 / 3) * d)
        up, dup = _min_jerk(np.clip(tau / rise, 0.0, 1.0))
        if hold_from_start:
            up, dup = np.ones_like(tau), np.zeros_like(tau)
        down, ddown = _min_jerk(np.clip((d - tau) / fall, 0.0, 1.0))
        if merged:  # the hold falls with the lift (rest_fall_profile)
            down, ddown = np.ones_like(tau), np.zeros_like(tau)
        r = up * down
        dr = np.where(tau < rise, dup / rise, 0.0) * down - np.where(tau > d - fall, ddown / fall, 0.0) * up
        nrm = np.outer(1 - m, n0) + np.outer(m, n1)
        nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
        base = base + nrm * (hold * r)[:, None]
        dbase = dbase + nrm * (hold * dr)[:, None]
    # Hermite corrections within ``w`` of each end: exact boundary velocities, local effect
    e0 = v0 - dbase[0]
    e1 = v1 - dbase[-1]
    a = np.clip(tau / w, 0.0, 1.0)
    b = np.clip((tau - (d - w)) / w, 0.0, 1.0)
    # start: the velocity error fades over ``w`` (a rebound carries on, it does not come back: a curve that
    # returned to the base would bring a rebounding stick back onto the head), and the displacement it made
    # is blended out over ``REBOUND_BLEND`` seconds
    g0 = (a - a**3 + a**4 / 2) * w
    dg0 = 1 - 3 * a**2 + 2 * a**3
    dg0[tau > w] = 0.0
    h11 = b**3 - b**2
    dh11 = 3 * b**2 - 2 * b
    dh11[tau < d - w] = 0.0
    span = min(d, REBOUND_BLEND)
    mb, dmb = _min_jerk(np.clip(tau / span, 0.0, 1.0))
    dmb = np.where(tau < span, dmb / span, 0.0)
    pos = base + np.outer(g0 * (1 - mb), e0) + np.outer(h11 * w, e1)
    vel = dbase + np.outer(dg0 * (1 - mb) - g0 * dmb, e0) + np.outer(dh11, e1)
    pos[0], pos[-1], vel[0], vel[-1] = p0, p1, v0, v1
    return t0 + tau, pos, vel


def kick_feet(notes: Iterable[Note | PlannedStroke]) -> set[Limb]:
    """The feet planned as bass-drum feet: each foot given a BASS note (assigned notes, or a plan's strokes: one
    per note). Such a foot rests on the raised footboard (``kick_rest_height``) and plays a stroke softer than the
    one before as a smaller, deeper stroke (``KICK_SOFTER_RISE``, ``KICK_DOUBLE_DEPTH``), so its stroke after a
    changed one differs too (the score player's live windows: ``FOOT_NOTES_AFTER``). With a double pedal either
    foot may be one."""
    return {n.limb for n in notes if n.event == EventType.BASS and n.limb in FEET}


def kick_contact_rise() -> float:
    """How far above the footboard pressed flat (the kick's target) the foot is when the beater meets the head,
    metres: the foot height that holds the board at ``BEATER_CONTACT_PRESS`` (``FOOT_PRESS_TABLE``; about 8 mm).
    A bass-drum foot's first stroke passes it at the note time and presses on to the flat board at its speed."""
    return foot_target_for_press(BEATER_CONTACT_PRESS)


def _softer(speed: float, previous: float) -> float:
    """How much softer a stroke at ``speed`` m/s is than the previous one at ``previous`` m/s: 0 (as loud or
    louder) ... 1 (half as fast or less)."""
    return float(np.clip(2.0 * (1.0 - speed / max(previous, 1e-6)), 0.0, 1.0))


def _brakes(pos: np.ndarray, vel: np.ndarray, normal: np.ndarray) -> bool:
    """Whether a stroke's knots (positions, velocities (K, 3) up to its contact) fall slower somewhere after their
    apex (the highest along ``normal``) than before: the foot brakes into the pedal (``KICK_BRAKE_TOLERANCE``)."""
    down = -(vel @ normal)[int(np.argmax(pos @ normal)):]
    return bool(np.any(np.maximum.accumulate(down) - down > KICK_BRAKE_TOLERANCE))


def _limb_knots(
    strokes: list[_Stroke],
    rest0: tuple[np.ndarray, np.ndarray],
    rest1_height: float,
    start: float,
    end: float,
    units: list[GestureUnit | None],
    cfg: PlannerConfig,
    cycle: float | None = None,
    hold: float = 0.0,
    on_laid: Callable[[int], None] | None = None,
    aims: list[np.ndarray] | None = None,
    previous: float | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Knots (times, positions, velocities) of one limb through its strokes; ``on_laid`` is told how many
    strokes are laid every ``PROGRESS_EVERY`` strokes; ``aims`` gets where each stroke meets its surface (its
    target, or deeper: ``KICK_DOUBLE_DEPTH``; a kick foot's stroke from rest higher: ``kick_contact_rise``);
    ``previous``: the limb's last stroke before these (s; None: none, its first is made from rest)."""
    times: list[np.ndarray] = []
    pos: list[np.ndarray] = []
    vel: list[np.ndarray] = []
    zero = np.zeros(3)
    p, v, n, t = rest0[0], zero, rest0[1], start
    held = False
    """The next segment starts at the hold (rest) height already: a foot's first stroke, or after a press-through."""
    if cycle is not None and hold != 0.0:  # a foot starts held at its rest (its base path on the pedal line)
        held = True
    for i, (st, unit) in enumerate(zip(strokes, units, strict=True)):
        if on_laid is not None and i and i % PROGRESS_EVERY == 0:
            on_laid(i)
        speed = st.speed  # at the pedal, m/s: slower in a run of fast kicks (KICK_RUN_GAP_S)
        if cycle is not None and hold > 0.0 and i >= 2:
            gaps = st.time - strokes[i - 1].time, strokes[i - 1].time - strokes[i - 2].time
            if max(gaps) < KICK_RUN_GAP_S:
                speed *= 1.0 - min(KICK_RUN_SLOWER * (KICK_RUN_GAP_S - gaps[0]), KICK_RUN_SLOWER_MAX)
        strike_v = -speed * st.normal
        lift = st.lift
        target = st.target
        if cycle is None and i > 0 and not st.bounce:
            # clear the surface after a contact: the rebound carries the stick up and a move to another
            # target must not drag it over the head (a soft stroke after a loud one has a tiny lift)
            away = np.linalg.norm((st.target - p)[:2])
            need = CLEARANCE + REBOUND_CLEARANCE * float(np.linalg.norm(v)) + MOVE_CLEARANCE * float(away)
            lift = max(lift, min(need, 0.9 * (st.time - t)))
        rest_rise = hold if (i > 0 or cycle is not None) else 0.0
        if cycle is not None and lift + rest_rise > 0:
            # a foot lifts only as high as it can rise and fall in the time it has (fast doubles are heel-toe
            # strokes from the footboard, not full lifts at several metres per second)
            # a bass-drum stroke softer than the previous one: a smaller stroke from where the board is, and deeper
            softer = _softer(st.speed, strokes[i - 1].speed) if hold > 0.0 and i > 0 else 0.0
            rise_speed = FOOT_RISE_SPEED * (1.0 - (1.0 - KICK_SOFTER_RISE) * softer)
            scale = min(1.0, rise_speed * (st.time - t) / (lift + rest_rise))
            lift, rest_rise = lift * scale, rest_rise * scale
            if softer > 0.0 and scale < 1.0:
                target = st.target - KICK_DOUBLE_DEPTH * (1.0 - scale) * softer * st.normal
        # a bass-drum foot's stroke from its rest (its first, or KICK_REST_GAP_S after the one before, a live plan's
        # first also after the foot's last stroke played before it: ``previous``; with room before the next:
        # KICK_RAISE_ROOM_S) passes the height where the beater meets the head
        # (``kick_contact_rise``) at the note time and presses on to the flat board at its speed: aimed at the flat
        # board, it sounded early by the time the foot takes over the last 8 mm (a lone kick at velocity 0.5 11 ms,
        # 0.2 21 ms; now 4 and 9). Not the strokes soon after another: the footboard under the held foot settles
        # for about 0.7 s after a stroke, and until it has the same foot height presses the board less, so they meet
        # the head about at the flat board (raised, kicks 0.1-0.4 s after another sounded 8-22 ms late;
        # docs/physics.md, "Kicks")
        through = 0.0
        rest_fall = 0.0
        bottom = target
        before = strokes[i - 1].time if i else previous  # the foot's stroke before (a live plan's: played before it)
        # ... and part of the way after a shorter gap, the footboard under the held foot still settling
        # (KICK_RAISE_FROM_S)
        gap = np.inf if before is None else st.time - before
        if cycle is not None and hold > 0.0 and gap > KICK_RAISE_FROM_S:
            rise = kick_contact_rise() * min((gap - KICK_RAISE_FROM_S) / (KICK_REST_GAP_S - KICK_RAISE_FROM_S), 1.0)
            pressed = st.time + rise / max(st.speed, 1e-3) + st.contact  # the contact's end, raised
            # a raise the foot passes within KICK_RAISE_MIN_S (a gap a hair over KICK_RAISE_FROM_S) is none: its
            # press-on knot would fall on the note's and the plan fail ("times must be strictly increasing")
            if rise / max(st.speed, 1e-3) >= KICK_RAISE_MIN_S and (
                    i + 1 == len(strokes) or strokes[i + 1].time - pressed >= KICK_RAISE_ROOM_S):
                through = rise
                target = target + through * st.normal
                rest_rise = max(rest_rise - through, 0.0)  # from the raised aim: the same rest height
            # raised or not (a kick just before the next): if its foot would brake into the pedal, the rest height
            # and the lift fall together, speeding up into the stroke (rest_fall_profile)
            rest_fall = KICK_REST_FALL * (lift + rest_rise) / max(st.speed, 1e-3)
        if aims is not None:
            aims.append(target)
        # rebound not yet finished: the lift also has to account for where we start
        tt, pp, vv = _segment(
            t, p, v, n, st.time, target, strike_v, st.normal, lift, unit, cfg.knots_per_second, cycle,
            rest_rise, hold_from_start=held,
        )
        if rest_fall > 0.0 and _brakes(pp, vv, st.normal):
            tt, pp, vv = _segment(
                t, p, v, n, st.time, target, strike_v, st.normal, lift, unit, cfg.knots_per_second, cycle,
                rest_rise, hold_from_start=held, rest_fall=rest_fall,
            )
        times.append(tt[:-1])
        pos.append(pp[:-1])
        vel.append(vv[:-1])
        if cycle is not None and hold < 0.0:
            # a foot whose rest is below its target (the hi-hat foot: the chick is on the way down) presses
            # through to its rest, slowing evenly, and stays there: no rebound, which left the footboard short of
            # the closing point in fast strokes
            c = 2.0 * -hold / max(st.speed, 1e-3)
            times.append(np.array([st.time]))
            pos.append(st.target[None, :])
            vel.append(strike_v[None, :])
            t, p, v, n = st.time + c, st.target + hold * st.normal, zero, st.normal
            held = True
            continue
        held = False
        c = st.contact
        depth = st.speed * c / 4
        t_bottom = st.time
        if through > 0.0:  # on at the stroke's speed from the contact height to the pressed board
            t_bottom = st.time + through / max(st.speed, 1e-3)
            times.append(np.array([st.time]))
            pos.append(target[None, :])
            vel.append(strike_v[None, :])
            target = bottom
        times.append(np.array([t_bottom, t_bottom + c / 2]))
        pos.append(np.array([target, target - depth * st.normal]))
        vel.append(np.array([strike_v, zero]))
        t = t_bottom + c
        p = target - (st.speed - st.rebound) * c / 4 * st.normal
        v = st.rebound * st.normal
        n = st.normal
    if strokes:
        last = strokes[-1]
        goal = last.target + rest1_height * last.normal
        # leave the surface at once after the last stroke (a slow rise lets the rebounding stick or beater
        # fall back onto the head), then hold at the rest height
        t_up = t + min(max(end - t, 0.2), TAIL_RISE)
        tt, pp, vv = _segment(t, p, v, n, t_up, goal, zero, n, 0.0, None, cfg.knots_per_second)
        times.append(tt)
        pos.append(pp)
        vel.append(vv)
        if end > t_up + 1e-3:
            times.append(np.array([end]))
            pos.append(goal[None, :])
            vel.append(zero[None, :])
    else:
        times.append(np.array([start, end]))
        pos.append(np.array([p, p]))
        vel.append(np.array([zero, zero]))
    return np.concatenate(times), np.concatenate(pos), np.concatenate(vel)


def _open_hihat(
    times: np.ndarray,
    pos: np.ndarray,
    vel: np.ndarray,
    opens: list[float],
    foot_strokes: list[float],
    cfg: PlannerConfig,
    closed: Sequence[float] = (),
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lift the hi-hat foot (pedal up, hi-hat open) around open hi-hat notes when the foot is resting.

    Windows [t - 80 ms, t + 120 ms] of open notes are merged (when no closed hi-hat note, ``closed``, lies between
    them); the pedal rises over the 0.1 s before a window and falls over ``hihat_close_s`` after it. A lift above
    ``HIHAT_CLOSE_TAIL_M`` falls quickly to the path a fall from that height would take at
    ``HIHAT_CLOSE_TAIL_FROM`` of it and follows it from there: the plates meet when and as slowly as they did after
    a lift of that height. A window is used only when the foot plays no pedal stroke within ``foot_cycle`` of it
    (its lift would start inside), but for a pedal stroke after its open notes and before the next closed one:
    that chick is the close, the foot coming down into it from the lift (at its planned contact and speed).

    The closed hi-hat notes around a window shape it, as a drummer opens after the previous closed stroke and
    closes for the next one: the rise starts ``HIHAT_OPEN_AFTER_S`` after the previous one (and ends at the
    latest ``HIHAT_OPEN_LEAD_S`` before the open note), the plates meet (``HIHAT_MEET_FRACTION`` into the fall)
    ``HIHAT_CLOSED_BY_S`` before the next one: the hold after the note shrinks first (to ``HIHAT_OPEN_HOLD_S``),
    then the fall. A shorter rise or fall lifts less, in proportion (at 16ths at 120 bpm, 7 cm lifted over 0.1 s
    and let down over 0.2 s took in the closed notes on either side: open).
    """
    hat = sorted(closed)
    windows: list[list[float]] = []
    for t in sorted(opens):
        between = windows and bisect.bisect_right(hat, windows[-1][3]) < bisect.bisect_left(hat, t)
        if windows and not between and t - 0.08 - 0.1 <= windows[-1][1] + cfg.hihat_close_s:
            windows[-1][1], windows[-1][3] = t + 0.12, t  # no close and reopen between
        else:
            windows.append([t - 0.08, t + 0.12, t, t])  # [lift reached, let down from, first and last note]
    strokes = np.sort(np.array(foot_strokes, dtype=float))
    # the knots of each window: (times, lifts above rest (m), vertical velocities (m/s), the rest under a chick it
    # joins or None), from its rise's start to its fall's end (or the chick's contact, a knot of the track kept)
    shapes: list[tuple[list[float], list[float], list[float], np.ndarray | None]] = []
    for w0, w1, t0, t1 in windows:
        a, b = w0 - 0.1, w1 + cfg.hihat_close_s
        i = bisect.bisect_left(hat, t0)
        before = hat[i - 1] if i else -np.inf
        after = hat[bisect.bisect_right(hat, t1)] if bisect.bisect_right(hat, t1) < len(hat) else np.inf
        k = int(np.searchsorted(strokes, a - cfg.foot_cycle, side="right"))  # the first stroke after a - cycle
        chick = None  # a pedal stroke after the open notes, before any closed one: it closes the hi-hat
        if k < len(strokes) and strokes[k] < b + cfg.foot_cycle + 0.01:
            if not t1 + HIHAT_OPEN_HOLD_S + HIHAT_OPEN_MIN_S < strokes[k] < after:
                continue
            chick = float(strokes[k])
        lift, fall = cfg.hihat_open_lift, cfg.hihat_close_s
        if before + HIHAT_OPEN_AFTER_S > a:  # the rise after the previous closed stroke, shorter: a lower lift
            a = before + HIHAT_OPEN_AFTER_S
            w0 = min(max(w0, a + 0.1), t0 - HIHAT_OPEN_LEAD_S)
            if w0 - a < HIHAT_OPEN_MIN_S:
                continue
            lift = min(lift, cfg.hihat_open_lift * (w0 - a) / 0.1)
        if chick is not None:
            # the foot holds the pedal up and comes down into the chick: the chick's own knot (its contact, at its
            # strike velocity) is kept, and the foot leaves the lift as far before it as a fall at 2/3 of that
            # speed takes (a cubic into the strike velocity, never braking before it); with less time, a lower lift
            j = int(np.searchsorted(times, chick, side="left"))
            if j == 0 or j >= len(times) or abs(times[j] - chick) > 1e-9 or a <= times[0]:
                continue
            speed = max(float(np.linalg.norm(vel[j])), 1e-3)
            # the lift from the foot's rest under the chick (the track at a may be on the chick's own way up)
            rest = pos[j] - cfg.foot_rest_height * vel[j] / speed
            above = float(pos[j][2] - rest[2])  # the chick's contact over the rest, metres
            down = min(1.5 * (lift - above) / speed, chick - t1 - HIHAT_OPEN_HOLD_S)
            lift = min(lift, above + down * speed / 1.5)
            if down < HIHAT_OPEN_MIN_S or lift < above + 0.01:
                continue
            shapes.append(([a, w0, chick - down, chick], [0.0, lift, lift, 0.0], [0.0, 0.0, 0.0, 0.0], rest))
            continue
        room = after - HIHAT_CLOSED_BY_S - t1  # from the last open note to the plates' meeting
        if room < 0.12 + HIHAT_MEET_FRACTION * fall:  # the hold after the note shorter, then the fall
            w1 = t1 + max(room - HIHAT_MEET_FRACTION * fall, HIHAT_OPEN_HOLD_S)
            fall = min(fall, (after - HIHAT_CLOSED_BY_S - w1) / HIHAT_MEET_FRACTION)
            if fall < HIHAT_OPEN_MIN_S:
                continue
            lift = min(lift, cfg.hihat_open_lift * fall / cfg.hihat_close_s)
            b = w1 + fall
        knots_t, knots_h, knots_v = [a, w0, w1], [0.0, lift, lift], [0.0, 0.0, 0.0]
        if lift > HIHAT_CLOSE_TAIL_M:
            u = HIHAT_CLOSE_TAIL_FROM  # a zero-velocity cubic fall of height H over D: H (1 - 3u^2 + 2u^3) at u = t/D
            knots_t.append(w1 + u * fall)
            knots_h.append(HIHAT_CLOSE_TAIL_M * (1.0 - 3.0 * u**2 + 2.0 * u**3))
            knots_v.append(-HIHAT_CLOSE_TAIL_M * 6.0 * u * (1.0 - u) / fall)
        shapes.append((knots_t + [b], knots_h + [0.0], knots_v + [0.0], None))
    # a window's let-down may reach past the next one's rise (a closed note between them): it ends sooner
    for j in range(len(shapes) - 1):
        ts, nxt = shapes[j][0], shapes[j + 1][0][0]
        if ts[-1] >= nxt and shapes[j][3] is None:
            ts[-1] = nxt - 1e-3
            while len(ts) > 2 and ts[-2] >= ts[-1] - 1e-3:  # a tail knot it overtook
                for part in shapes[j][:3]:
                    del part[-2]
    # one pass, splicing each window in where it falls: windows are disjoint and increasing, so the knots around
    # a window are the last one spliced in and the originals after it (re-sorting the whole track per window
    # made a long score with many open hi-hats quadratic: 200,000 notes took minutes)
    out_t: list[np.ndarray] = []
    out_p: list[np.ndarray] = []
    out_v: list[np.ndarray] = []
    done = 0  # originals before this index are out (kept or replaced)
    zero = np.zeros(3)
    for knots_t, knots_h, knots_v, chick_rest in shapes:
        joins = chick_rest is not None
        a, b = knots_t[0], knots_t[-1]
        if a <= times[0] or b >= times[-1] or knots_t[1] <= a or (out_t and a <= out_t[-1][-1]):
            continue
        # originals in [lo, hi) lie in [a, b] (or a hair outside: a window shaped by its neighbours can end on a
        # knot of the track, a time the physics then saw twice): replaced
        lo = int(np.searchsorted(times, a - 1e-6, side="left"))
        hi = int(np.searchsorted(times, b, side="left")) if joins else int(np.searchsorted(times, b + 1e-6, "right"))
        if joins:  # the chick's knot (at b) and the track after it kept
            knots_t, knots_h, knots_v = knots_t[:-1], knots_h[:-1], knots_v[:-1]
        near = slice(done, hi + 1)  # up to the first original after b (b < times[-1])
        if out_t:  # the window before ends with its knot at its b, before these originals
            ends, ends_v = hermite(np.concatenate([out_t[-1][-1:], times[near]]),
                                   np.concatenate([out_p[-1][-1:], pos[near]]),
                                   np.concatenate([out_v[-1][-1:], vel[near]]), np.array([a, b]))
        else:
            ends, ends_v = hermite(times[near], pos[near], vel[near], np.array([a, b]))
        rest_a, rest_b = ends[0], ends[1]
        rests = [rest_a, rest_a] + [rest_b] * (len(knots_t) - 2)
        knots_p = [r + np.array([0.0, 0.0, h]) for r, h in zip(rests, knots_h, strict=True)]
        knots_vv = [zero if v == 0.0 else np.array([0.0, 0.0, v]) for v in knots_v]
        if chick_rest is not None:  # from the track as it is at a (on the way up to the chick, maybe) to the lift
            knots_p = [rest_a] + [chick_rest + np.array([0.0, 0.0, h]) for h in knots_h[1:]]
            knots_vv[0] = ends_v[0]
        out_t += [times[done:lo], np.array(knots_t)]
        out_p += [pos[done:lo], np.array(knots_p)]
        out_v += [vel[done:lo], np.array(knots_vv)]
        done = hi
    if not out_t:
        return times, pos, vel
    out_t.append(times[done:])
    out_p.append(pos[done:])
    out_v.append(vel[done:])
    return np.concatenate(out_t), np.concatenate(out_p), np.concatenate(out_v)


def _rest_event(kit: Kit, limb: Limb) -> EventType | None:
    swap = {
        Limb.LEFT_HAND: Limb.RIGHT_HAND,
        Limb.RIGHT_HAND: Limb.LEFT_HAND,
        Limb.LEFT_FOOT: Limb.RIGHT_FOOT,
        Limb.RIGHT_FOOT: Limb.LEFT_FOOT,
    }
    order = _rest_event_order(swap[limb] if kit.handedness == "left" else limb)
    for ev in order:
        if ev in kit.events:
            return ev
    for ev, spec in kit.events.items():
        if spec.preferred == limb:
            return ev
    return next(iter(kit.events), None)


def _rest_event_order(limb: Limb) -> list[EventType]:
    return {
        Limb.LEFT_HAND: [EventType.SNARE],
        Limb.RIGHT_HAND: [EventType.HIHATCLOSED, EventType.RIDE],
        Limb.LEFT_FOOT: [EventType.HIHATPEDAL],
        Limb.RIGHT_FOOT: [EventType.BASS],
    }[limb]


def plan_gestures(
    assignment: Assignment,
    kit: Kit,
    score: Score | None = None,
    config: PlannerConfig | None = None,
    database: GestureDatabase | None = None,
    progress: ProgressCallback | None = None,
    last_strokes: Mapping[Limb, float] | None = None,
) -> GesturePlan:
    """Plan Cartesian effector trajectories for an assignment.

    Parameters
    ----------
    assignment : Assignment
        Notes with limbs (from :func:`common.score.limbs.distribute`).
    kit : Kit
        Hit points, normals, elasticities.
    score : Score | None
        For the beats (head nod).
    config : PlannerConfig | None
        Grip, global nuance, timing.
    database : GestureDatabase | None
        Gesture units (default: the shipped database).
    progress : Callable[[int, int], None] | None
        Called with (notes done, notes total), ``total`` the assignment's notes and ``done`` those whose
        trajectory is laid (limb after limb, the bulk of the work): ``(0, total)`` first, ``(total, total)``
        last, and between at least once every ``PROGRESS_EVERY`` notes laid and at the end of each limb.
        Whatever it raises (``KeyboardInterrupt``) stops the planning. The plan is the same with or without it.
    last_strokes : Mapping[Limb, float] | None
        Each limb's last stroke before the assignment's notes (seconds, the notes' clock): a live plan spliced
        into a performance (services/physics/score_player.py). A bass-drum foot's first stroke here is made from
        rest (``KICK_REST_GAP_S``) only that long after it; a limb not in it (or None) has played nothing before.

    Returns
    -------
    GesturePlan
        One trajectory per limb, every note's planned stroke, the assignment's issues.
    """
    cfg = config or PlannerConfig()
    db = database or default_database()
    notes = assignment.notes
    first = notes[0].time if notes else 0.0
    last = notes[-1].time if notes else 0.0
    start, end = first - cfg.lead_in, last + cfg.tail
    trajectories: dict[Limb, LimbTrajectory] = {}
    planned: list[PlannedStroke] = []
    geometry: dict[tuple[EventType, int | None, Limb], tuple[np.ndarray, np.ndarray, np.ndarray, KitObject]] = {}
    laid = 0  # notes of the limbs done so far
    if progress is not None:
        progress(0, len(notes))
    kicking = kick_feet(notes)
    for limb in Limb:
        mine = [n for n in notes if n.limb == limb]
        hand = limb in HANDS
        strokes: list[_Stroke] = []
        units: list[GestureUnit | None] = []
        prev_time = start
        for n in mine:
            nuance = n.nuance or cfg.nuance
            key = (n.event, n.pitch, limb)
            if key not in geometry:
                tgt, nrm = kit.effector_target(n.event, limb, n.pitch)
                geometry[key] = (
                    np.array(tgt),
                    np.array(nrm),
                    np.array(tgt if hand else kit.hit_point(n.event, n.pitch)[0]),  # a hand's own point (off_hand)
                    kit.object_for(n.event, n.pitch),
                )
            target, normal, hit, obj = geometry[key]
            interval = n.time - prev_time
            if hand:
                unit = db.select(cfg.grip, nuance, interval)
                lift = tempo_cap(stick_height(n.velocity, nuance), interval)
                speed = stick_speed(n.velocity, nuance)
                contact = unit.contact_duration
                rebound = obj.elasticity * speed
                if n.rebound and strokes:
                    lift = bounce_height(strokes[-1].rebound, speed, interval - strokes[-1].contact, lift)
            else:
                unit = db.select(cfg.grip, Nuance.LEGATO, interval)
                lift = tempo_cap(foot_height(n.velocity), interval)
                speed = chick_speed(n.velocity) if n.event == EventType.HIHATPEDAL else foot_speed(n.velocity)
                contact = cfg.foot_contact
                rebound = 0.5 * obj.elasticity * speed
            bounce = hand and n.rebound and bool(strokes)
            strokes.append(_Stroke(n.time, target, normal, speed, rebound, lift, contact, nuance, bounce))
            units.append(unit)
            struck_r, struck_theta = kit.struck_point(n.event, limb)
            planned.append(
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
                    lift=lift,
                    rebound_velocity=rebound,
                    contact_duration=contact,
                    grip=cfg.grip,
                    nuance=nuance,
                    rebound_double=bounce,
                )
            )
            prev_time = n.time
        kick_foot = not hand and (
            limb in kicking or (not mine and _rest_event(kit, limb) == EventType.BASS)
        )
        rest_h = cfg.rest_height if hand else (cfg.kick_rest_height if kick_foot else cfg.foot_rest_height)
        if strokes:
            rest0 = (strokes[0].target + rest_h * strokes[0].normal, strokes[0].normal)
        else:
            ev = _rest_event(kit, limb)
            if ev is None:
                continue
            if (not hand and kit.spec(ev).pedal is not None
                    and (limb, kit.pedal_for(ev, limb)) in assignment.pedals_out_of_reach):
                continue  # no trajectory: the foot stays as the body rests it (stretched, it pulled the hands along)
            rest_target, rest_normal = (np.array(v) for v in kit.effector_target(ev, limb))
            rest0 = (rest_target + rest_h * rest_normal, rest_normal)
        on_laid = None if progress is None else lambda k, before=laid: progress(before + k, len(notes))
        aims: list[np.ndarray] = []
        times, pos, vel = _limb_knots(strokes, rest0, rest_h, start, end, units, cfg, None if hand else cfg.foot_cycle,
                                      0.0 if hand else rest_h,  # a foot rests at its rest height between strokes
                                      on_laid, aims, (last_strokes or {}).get(limb))
        first = len(planned) - len(strokes)  # this limb's strokes, in order
        for k, (st, aim) in enumerate(zip(strokes, aims, strict=True)):
            if aim is not st.target:  # a bass-drum stroke aimed deeper: the plan meets the surface there
                planned[first + k] = replace(planned[first + k], target=aim)
        laid += len(strokes)
        if progress is not None:
            progress(laid, len(notes))
        if EventType.HIHATPEDAL in kit.events and limb == kit.spec(EventType.HIHATPEDAL).preferred:
            opens = [n.time for n in notes if n.event == EventType.HIHATOPEN]
            hat_closed = [n.time for n in notes if n.event == EventType.HIHATCLOSED]
            times, pos, vel = _open_hihat(times, pos, vel, opens, [s.time for s in strokes], cfg, hat_closed)
        trajectories[limb] = LimbTrajectory(limb, times, pos, vel)
    planned.sort(key=lambda s: (s.time, s.limb.value))
    plan_end = max((tr.end_time for tr in trajectories.values()), default=end)
    head = _head(planned, score, start, plan_end, cfg)
    if progress is not None:
        progress(len(notes), len(notes))
    return GesturePlan(
        trajectories=trajectories,
        strokes=planned,
        issues=list(assignment.issues),
        head=head,
        start_time=start,
        end_time=plan_end,
        kit_name=kit.name,
        mode="gesture",
    )


def _head(
    strokes: list[PlannedStroke], score: Score | None, start: float, end: float, cfg: PlannerConfig
) -> HeadTrajectory:
    """Look-at point: the hands' hit points, smoothed over 0.25 s; nod: a bump on every beat."""
    t = np.arange(start, end + 1.0 / cfg.head_rate, 1.0 / cfg.head_rate)
    hand = [s for s in strokes if s.limb in HANDS]
    if hand:
        st = np.array([s.time for s in hand])
        pts = np.array([s.hit_point for s in hand])
        targets = np.stack([np.interp(t, st, pts[:, k]) for k in range(3)], axis=1)
        width = max(1, int(0.25 * cfg.head_rate))
        kernel = np.ones(width) / width
        padded = np.pad(targets, ((width, width), (0, 0)), mode="edge")
        targets = np.stack([np.convolve(padded[:, k], kernel, mode="same")[width:-width] for k in range(3)], axis=1)
    else:
        targets = np.tile([0.0, 0.5, 0.7], (len(t), 1))
    nod = np.zeros_like(t)
    beats = score.beats if score is not None and len(score.beats) else np.zeros(0)
    # each bump only where exp() does not underflow to exactly 0: the same sums, but a long score's beats no
    # longer each sweep the whole head track (3 h of beats took minutes, a day's ran out of memory)
    reach = NOD_REACH * cfg.nod_width
    for b in beats:
        if start - 1 <= b <= end + 1:
            lo, hi = np.searchsorted(t, [b - reach, b + reach])
            nod[lo:hi] += cfg.nod_amplitude * np.exp(-(((t[lo:hi] - b) / cfg.nod_width) ** 2))
    return HeadTrajectory(t, targets, nod)


def plan_score(
    score: Score,
    kit: Kit,
    algorithm: HandAlgorithm | str = HandAlgorithm.VITERBI,
    sticking: Sticking | str = Sticking.NONE,
    config: PlannerConfig | None = None,
    database: GestureDatabase | None = None,
) -> GesturePlan:
    """Score -> limbs -> gesture plan, in one call."""
    assignment = distribute(score, kit, algorithm, sticking)
    return plan_gestures(assignment, kit, score, config, database)


__all__ = ["Note", "PlannerConfig", "plan_gestures", "plan_score"]
