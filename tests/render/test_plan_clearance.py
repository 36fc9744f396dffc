"""The plan touches an instrument only at its notes: between strokes the stick tip stays above the surface.

A stick tip that reaches the head before its note (or lingers on it after)
makes physics play extra notes; the evaluation found one at about 80 ms
before every hi-hat eighth note when the gesture units' profiles rested at
the contact height for part of their cycle (fixed in common/gesture/database.py).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from batteur.render import RenderOptions, prepare
from common.gesture.database import default_database
from common.gesture.plan import Grip, Nuance
from common.kit import KitObject, Limb, load_kit

HERE = Path(__file__).parent
SCORES = [HERE / "short_groove.txt", HERE.parent / "data" / "groove_drummer6_s3_1_rock_90_beat_4-4.mid"]
GUARD_S = 0.006
"""Time around each planned contact (its approach and contact) left out of the check, seconds."""


def _height_above_surface(obj: KitObject, points: np.ndarray) -> np.ndarray:
    """Height (metres) of world points (n, 3) above the object's playing surface under them: its plane, or a
    cymbal's bell top within the bell radius."""
    rot = np.array(obj.rotation_matrix())
    local = (points - np.array(obj.position)) @ rot  # world -> local: R^T p
    r = np.hypot(local[:, 0], local[:, 1])
    return local[:, 2] - np.array([obj.surface_height(float(x)) for x in r])


@pytest.mark.parametrize("score", SCORES, ids=lambda p: p.name)
def test_hands_stay_above_the_next_surface_between_strokes(score: Path) -> None:
    kit = load_kit()
    _, _, plan = prepare(score, kit, RenderOptions())
    worst = np.inf
    for limb in (Limb.LEFT_HAND, Limb.RIGHT_HAND):
        strokes = plan.strokes_of(limb)
        traj = plan.trajectories[limb]
        for prev, nxt in zip(strokes, strokes[1:], strict=False):
            if nxt.time - prev.time < 4 * GUARD_S or nxt.object_id != prev.object_id:
                continue
            t = np.arange(prev.time + prev.contact_duration + GUARD_S, nxt.time - GUARD_S, 0.001)
            pos, _ = traj.sample_many(t)
            height = _height_above_surface(kit.object(nxt.object_id), pos)
            worst = min(worst, float(height.min()))
            assert height.min() > 0.001, (
                f"{limb.value}: tip {height.min() * 1000:.1f} mm from {nxt.object_id} at "
                f"{t[int(np.argmin(height))]:.3f} s, between notes at {prev.time:.3f} and {nxt.time:.3f} s")
    assert np.isfinite(worst)


@pytest.mark.parametrize("nuance", list(Nuance))
def test_unit_profiles_are_positive_between_contacts(nuance: Nuance) -> None:
    db = default_database()
    for interval in (0.25, 0.375, 0.6, 1.0):
        unit = db.select(Grip.GERMAN, nuance, interval)
        phi = np.linspace(0.02, 0.98, 97)
        assert unit.profile(phi).min() > 0.0, unit.name
