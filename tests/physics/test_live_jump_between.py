"""A live core whose targets trail the rig clock (tests/physics/test_live_catch_up.py) jumps them to it where that
goes unnoticed (``DrummerScene.can_jump``). Until 7 Dec the test looked only at the jump's two ends: a hand at
rest before a stroke and back at rest after it matched at both, so the jump passed over the whole stroke and its
note was lost. It now also looks between the two: every planned stroke's span, and the targets sampled every
``JUMP_SAMPLE_S`` (a streamed stroke has no planned strike). Past ``MAX_TARGET_LAG_S`` a jump still drops the
strokes wholly between its ends (``drop_strokes``), as documented.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import pytest

from common.kit import EventType
from common.messages.physics import PhysicsReset
from services.physics.core import LATE_JUMP_MAX_M, LATE_JUMP_MAX_SPEED_M_S, PhysicsCore
from services.physics.drummer import JUMP_MAX_M, DrummerScene
from services.physics.follow_through import Strike
from services.physics.strokes import strokes_knots

NOTE_S = 1.0
"""Rig time of the stroke between the two rests, seconds (its knots: 0.12 s before it to 0.15 s after)."""


@pytest.fixture
def scene(drummer: PhysicsCore) -> Iterator[DrummerScene]:
    """The module's drummer scene, its targets cleared after the test."""
    assert isinstance(drummer.scene, DrummerScene)
    yield drummer.scene
    drummer.handle(PhysicsReset(time=0.0), 0.0, "")


def snare(scene: DrummerScene) -> tuple[np.ndarray, np.ndarray]:
    """The snare's hit point (m) and its surface normal."""
    spec = scene.kit.events[EventType.SNARE]
    obj = scene.kit.object(spec.object)
    r = spec.r * obj.radius
    return np.array(obj.to_world((r * math.cos(spec.theta), r * math.sin(spec.theta), 0.0))), np.array(obj.normal())


def stroke_between_rests(scene: DrummerScene, hit: np.ndarray, normal: np.ndarray) -> None:
    """The left stick at rest from 0.5 s, down onto ``hit`` at ``NOTE_S`` and back to rest, held to 1.6 s."""
    rest = scene.rest_targets["left_hand"]
    scene.add_cartesian("left_hand", 0.5, rest, np.zeros(3), 0.0)
    ts, ps, vs = strokes_knots(rest, hit, normal, [NOTE_S], [2.0])
    for t, p, v in zip(ts, ps, vs, strict=True):
        scene.add_cartesian("left_hand", float(t), p, v, 0.0)
    scene.add_cartesian("left_hand", 1.6, rest, np.zeros(3), 0.0)


def test_a_jump_over_a_streamed_stroke_between_two_rests_is_refused(scene: DrummerScene) -> None:
    hit, normal = snare(scene)
    stroke_between_rests(scene, hit, normal)
    track = scene.limb_tracks["left_hand"]
    (p0, v0), (p1, v1) = track.sample(0.7), track.sample(1.4)
    assert np.allclose(p0, p1) and np.allclose(v0, v1)  # the two ends match: only the look between can tell
    assert not scene.can_jump(0.7, 1.4)  # was allowed: the stroke, and its note, jumped over
    assert scene.can_jump(0.55, 0.85) and scene.can_jump(1.2, 1.55)  # the rests themselves still allow it
    # past MAX_TARGET_LAG_S the core drops the strokes wholly between (only the ends are checked)
    assert scene.can_jump(0.7, 1.4, LATE_JUMP_MAX_M, LATE_JUMP_MAX_SPEED_M_S, drop_strokes=True)


def test_a_jump_over_a_planned_stroke_is_refused_even_where_its_target_barely_moves(scene: DrummerScene) -> None:
    """A planned ghost note whose target moves less than ``JUMP_MAX_M`` (sampling alone would pass it): its
    planned strike's span refuses the jump."""
    hit, normal = snare(scene)
    rest = hit + 0.5 * JUMP_MAX_M * normal  # 1 cm above the head
    scene.add_cartesian("left_hand", 0.5, rest, np.zeros(3), 0.0)
    ts, ps, vs = strokes_knots(rest, hit, normal, [NOTE_S], [0.1])
    for t, p, v in zip(ts, ps, vs, strict=True):
        scene.add_cartesian("left_hand", float(t), p, v, 0.0)
    scene.add_cartesian("left_hand", 1.6, rest, np.zeros(3), 0.0)
    assert scene.can_jump(0.7, 1.4)  # unplanned, it moves too little to tell
    track = scene.limb_tracks["left_hand"]
    track.add_strike(Strike(NOTE_S, NOTE_S + 0.002, -normal, 0.1, "snare"))
    assert not scene.can_jump(0.7, 1.4)  # was allowed
    assert scene.can_jump(0.55, 0.8) and scene.can_jump(1.25, 1.55)  # outside the strike's span
    assert scene.can_jump(0.7, 1.4, drop_strokes=True)  # the ends alone: neither in the stroke
