"""Kits with an instrument moved to a chosen distance from the drummer, for reach tests."""

from __future__ import annotations

import numpy as np

from common.gesture.plan import FeasibilityIssue, IssueAction, IssueReason
from common.kit import EventType, Kit, Limb, load_kit
from common.score.limbs import SHOULDERS, shoulders

SMALL_M = 1.4
"""A small drummer's height (metres): hand reach 1.02 m."""


def china_moved(kit: Kit, hit_point: np.ndarray) -> Kit:
    """``kit`` with its china moved so its hit point is at ``hit_point`` (metres, kit frame)."""
    delta = hit_point - np.array(kit.hit_point(EventType.CHINA)[0])
    objects = [o.model_copy(update={"position": tuple(float(p + d) for p, d in zip(o.position, delta, strict=True))})
               if o.id == "china" else o for o in kit.objects]
    return kit.model_copy(update={"objects": objects})


def china_at(kit: Kit, distance_m: float) -> Kit:
    """``kit`` with its china's hit point ``distance_m`` (metres) from the default (1.75 m) drummer's right
    shoulder, out to its right and a little forward (1.10 m: within the default drummer's 1.15 m reach, beyond a
    1.40 m drummer's 1.02 m)."""
    shoulder = np.array(SHOULDERS[Limb.RIGHT_HAND])
    direction = np.array([0.95, 0.3, 0.0]) / np.linalg.norm([0.95, 0.3, 0.0])
    return china_moved(kit, shoulder + distance_m * direction)


def china_left(kit: Kit, height_m: float, from_left_m: float) -> Kit:
    """``kit`` with its china out to the left of a drummer ``height_m`` tall, ``from_left_m`` metres from its left
    shoulder (the china stays the right hand's by its preferred hand; its pair preferences, written for a china on
    the right, are dropped: crossing the arms 0.8 m they would give way to the geometry's, ``Kit.stale_pairs``)."""
    direction = np.array([-0.95, 0.3, 0.0]) / np.linalg.norm([-0.95, 0.3, 0.0])
    moved = china_moved(kit, np.array(shoulders(kit, height_m)[Limb.LEFT_HAND]) + from_left_m * direction)
    pairs = {key: p for key, p in moved.pair_preference.items() if EventType.CHINA.value not in key.split(",")}
    return moved.model_copy(update={"pair_preference": pairs})


FAR_LEFT = china_left(load_kit("default", warn=False), SMALL_M, 0.75)
"""The china in reach of the small drummer's left hand only (1.04 m from its right shoulder), and of both hands of
the default 1.75 m drummer (reach 1.15 m; 1.09 m from its right shoulder)."""


def unreachable(issues: list[FeasibilityIssue]) -> list[tuple[int, IssueAction]]:
    """(note index, action) of the feasibility issues that say a note is beyond reach."""
    return [(i.note_index, i.action) for i in issues if i.reason == IssueReason.UNREACHABLE]
