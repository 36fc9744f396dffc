"""The strikes in the glTF export: one thin emissive disc per struck kit object, lying on its head (a drum's
batter head, a cymbal's or the hi-hat's top plate), shown at each of its impacts and hidden again :data:`FLASH_S`
later by keying its node's scale (STEP keys) between a speck (:data:`HIDDEN_SCALE`) and its full size.

Core glTF 2.0 animates nodes only (a material's emissive needs the ``KHR_animation_pointer`` extension), so a
scaled node is what every viewer and importer plays.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterable, Mapping

import numpy as np
from scipy.spatial.transform import Rotation

from common.kit import KitObject

FLASH_S = 0.15
"""How long a flash stays lit after its impact, seconds (a later impact of the same object cuts it short)."""
FLASH_THICKNESS_M = 0.002
"""The disc's drawn thickness, metres."""
FLASH_LIFT_M = 0.001
"""How far above the drawn head the disc's underside lies, metres (so no part of it hides inside the head)."""
FLASH_COLOUR = [1.0, 0.93, 0.7]
"""The disc's emissive (and base) colour, linear RGB."""
HIDDEN_SCALE = 1e-4
"""The dark disc's scale on each axis (metres across: a speck; not 0, so its node's transform stays invertible
for the tools that invert it)."""
MIN_GAP_S = 1e-3
"""Impacts of one object closer than this (seconds) light one flash, and a flash cut short by the next goes dark
this much before it (glTF key times must increase, as float32: 1 ms stays apart for hours)."""


def flash_times(impacts: Iterable[tuple[float, str]], origin: float) -> dict[str, list[float]]:
    """Kit object id -> its impacts' key times (seconds from ``origin``, at least 0, sorted, merged when closer
    than :data:`MIN_GAP_S`), from ``impacts`` as (rig time in seconds, kit object id)."""
    out: dict[str, list[float]] = defaultdict(list)
    for time, instrument in sorted(impacts, key=lambda i: (i[1], i[0])):
        t = max(float(time) - origin, 0.0)  # glTF key times are not negative: a strike before time 0 shows at it
        if not out[instrument] or t - out[instrument][-1] >= MIN_GAP_S:
            out[instrument].append(t)
    return dict(out)


def scale_keys(times: list[float], full: list[float]) -> tuple[np.ndarray, np.ndarray]:
    """STEP keys of a flash's scale: :data:`HIDDEN_SCALE` from time 0 (or its first impact's, if before),
    ``full`` at each impact, hidden again :data:`FLASH_S` later or just before the next impact, whichever comes
    first. Returns (key times (N,), scales (N, 3)), seconds and scale factors."""
    keys: list[tuple[float, list[float]]] = []
    hidden = [HIDDEN_SCALE] * 3
    if times[0] > 0:
        keys.append((0.0, hidden))
    for k, t in enumerate(times):
        keys.append((t, full))
        off = t + FLASH_S
        if k + 1 < len(times) and off > times[k + 1] - MIN_GAP_S:  # the next comes first: dark just before it
            off = (t + times[k + 1]) / 2 if times[k + 1] - t < 2 * MIN_GAP_S else times[k + 1] - MIN_GAP_S
        keys.append((off, hidden))
    return np.array([t for t, _ in keys], np.float32), np.array([s for _, s in keys], np.float32)


def head_offset(obj: KitObject, plate_lift_m: float) -> float:
    """Where the disc lies along the drawn object's local z, metres: the drawn head or plate is its cylinder's top
    face (z=0; ``plate_lift_m`` higher for the hi-hat's top plate, drawn above its link frame), a box's top
    half its depth up."""
    above = FLASH_LIFT_M + FLASH_THICKNESS_M  # the unit cylinder hangs below its frame: its top face at z=0
    if obj.kind in ("membrane", "throne", "cymbal"):
        return above
    if obj.kind == "hihat":
        return plate_lift_m + above
    return max(obj.depth, 0.02) / 2 + above


def full_scale(obj: KitObject) -> list[float]:
    """The lit disc's scale on a unit cylinder (radius 1, height 1): the head's radius, :data:`FLASH_THICKNESS_M`."""
    return [float(obj.radius), float(obj.radius), FLASH_THICKNESS_M]


def static_place(obj: KitObject, plate_lift_m: float) -> tuple[list[float], list[float]]:
    """Translation and rotation (x y z w) of an unmoving object's disc in the kit's frame."""
    rot = Rotation.from_euler("xyz", obj.rotation_deg, degrees=True)
    pos = np.asarray(obj.position, dtype=float) + rot.apply([0.0, 0.0, head_offset(obj, plate_lift_m)])
    return [float(v) for v in pos], [float(v) for v in rot.as_quat()]


def struck_objects(objects: Iterable[KitObject], times: Mapping[str, list[float]]) -> list[KitObject]:
    """The kit objects with impacts, in the kit's order (impacts on ids not in the kit are left out)."""
    return [obj for obj in objects if obj.id in times]
