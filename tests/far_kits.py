"""Kits with an instrument moved to a chosen distance from the drummer, for reach tests."""

from __future__ import annotations

import numpy as np

from common.kit import EventType, Kit, Limb
from common.score.limbs import SHOULDERS


def china_at(kit: Kit, distance_m: float) -> Kit:
    """``kit`` with its china's hit point ``distance_m`` (metres) from the default (1.75 m) drummer's right
    shoulder, out to its right and a little forward (1.10 m: within the default drummer's 1.15 m reach, beyond a
    1.40 m drummer's 1.02 m)."""
    shoulder = np.array(SHOULDERS[Limb.RIGHT_HAND])
    direction = np.array([0.95, 0.3, 0.0]) / np.linalg.norm([0.95, 0.3, 0.0])
    delta = shoulder + distance_m * direction - np.array(kit.hit_point(EventType.CHINA)[0])
    objects = [o.model_copy(update={"position": tuple(float(p + d) for p, d in zip(o.position, delta, strict=True))})
               if o.id == "china" else o for o in kit.objects]
    return kit.model_copy(update={"objects": objects})
