"""Rebound doubles: when one hand may play two notes faster than a full stroke allows.

A full (wrist) stroke of one hand needs the event's ``min_time_gap`` before
the hand's next stroke. A *rebound double* (a diddle: the two notes of a
double-stroke roll, the grace notes of a drag) is one wrist stroke whose
bounce, steered by the fingers, plays a second note on the same spot: it can
follow the first note much sooner. sources and numbers: docs/gestures.md.

A same-hand pair (first note ``a``, second note ``b``) is a rebound double when
all of these hold:

* both are stick events (feet never bounce a double here),
* ``a`` is itself a full stroke (not the bounce of an earlier double: a third
  bounce is a buzz, not a controlled note),
* ``b`` is on the same kit object within ``REBOUND_REACH`` of ``a``'s hit point,
* ``b`` is not louder than ``a`` by more than ``Kit.rebound_velocity_margin``
  (a bounce is softer than or as loud as its stroke),
* the interval is at least :func:`rebound_gap` (``b``'s velocity).

Every interval of one hand is then one of: a full-stroke interval
(``>= min_time_gap``), a rebound double, or too fast.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

from common.kit import EventType, Kit

REBOUND_REACH = 0.05
"""Largest distance (metres) between the two hit points of a rebound double: the bounce lands on the same spot."""
REBOUND_SOFT_VELOCITY = 0.63
"""Score velocity (mf) up to which the kit's rebound minimum applies; above it the minimum rises linearly to the
full-stroke minTimeGap at velocity 1 (a loud bounce needs a higher stick, so more time)."""


class Interval(enum.StrEnum):
    """How a hand plays a note after its previous one."""

    FIRST = "first"  # the hand's first note
    FULL = "full"  # at least the event's minTimeGap: a full stroke
    REBOUND = "rebound"  # the bounce of a rebound double
    TOO_FAST = "too_fast"  # neither


@dataclass(frozen=True)
class Stroke:
    """What :func:`classify` needs of one note: time (s), event, MIDI pitch, velocity in [0, 1]."""

    time: float
    event: EventType
    pitch: int | None
    velocity: float


def is_stick(kit: Kit, event: EventType) -> bool:
    """True for events played with a stick (not a pedal)."""
    return kit.spec(event).pedal is None


def rebound_gap(kit: Kit, event: EventType, velocity: float) -> float:
    """Shortest interval (seconds) of a rebound double whose second note is ``event`` at ``velocity``.

    The event's ``rebound_min_time_gap`` (else the kit's) up to velocity
    ``REBOUND_SOFT_VELOCITY``, rising linearly to the full ``min_time_gap`` at velocity 1;
    never above the full minimum.
    """
    spec = kit.spec(event)
    full = spec.min_time_gap
    low = min(spec.rebound_min_time_gap or kit.rebound_min_time_gap, full)
    share = min(max((velocity - REBOUND_SOFT_VELOCITY) / (1.0 - REBOUND_SOFT_VELOCITY), 0.0), 1.0)
    return low + (full - low) * share


def same_spot(kit: Kit, a: Stroke, b: Stroke) -> bool:
    """True when ``b`` lands on ``a``'s object within ``REBOUND_REACH`` metres of ``a``'s hit point."""
    if kit.object_for(a.event, a.pitch).id != kit.object_for(b.event, b.pitch).id:
        return False
    pa, pb = kit.hit_point(a.event, a.pitch)[0], kit.hit_point(b.event, b.pitch)[0]
    return math.dist(pa, pb) <= REBOUND_REACH


def classify(kit: Kit, prev: Stroke | None, prev_is_rebound: bool, cur: Stroke) -> Interval:
    """How one hand can play ``cur`` after its previous note ``prev``.

    Parameters
    ----------
    kit : Kit
        minTimeGaps, rebound minimum, objects and hit points.
    prev : Stroke | None
        The hand's previous (kept) note, or None.
    prev_is_rebound : bool
        Whether ``prev`` was itself the bounce of a rebound double.
    cur : Stroke
        The note to play.
    """
    if prev is None:
        return Interval.FIRST
    dt = cur.time - prev.time
    if dt >= kit.spec(cur.event).min_time_gap - 1e-9:
        return Interval.FULL
    if (
        not prev_is_rebound
        and is_stick(kit, prev.event)
        and is_stick(kit, cur.event)
        and cur.velocity <= prev.velocity + kit.rebound_velocity_margin + 1e-9
        and dt >= rebound_gap(kit, cur.event, cur.velocity) - 1e-9
        and same_spot(kit, prev, cur)
    ):
        return Interval.REBOUND
    return Interval.TOO_FAST


def why_too_fast(kit: Kit, prev: Stroke, prev_is_rebound: bool, cur: Stroke) -> str:
    """Why ``cur`` after ``prev`` on one hand is neither a full stroke nor a rebound double (for reports)."""
    dt = cur.time - prev.time
    full = kit.spec(cur.event).min_time_gap
    head = f"{dt * 1000:.0f} ms after its last stroke (minTimeGap {full * 1000:.0f} ms"
    if not (is_stick(kit, prev.event) and is_stick(kit, cur.event)):
        return head + ")"
    if prev_is_rebound:
        return head + "; the last stroke was already a bounce)"
    if not same_spot(kit, prev, cur):
        return head + f"; not a rebound double: {prev.event.value} then {cur.event.value} on another spot)"
    if cur.velocity > prev.velocity + kit.rebound_velocity_margin + 1e-9:
        return head + "; not a rebound double: louder than its stroke)"
    return head + f"; rebound minimum {rebound_gap(kit, cur.event, cur.velocity) * 1000:.0f} ms)"
