"""Postures from the graphics pose editor (/batteur/physics/posture): a separate handler of the physics core.

The editor may send angles outside the joint limits (it does not know them): they
are clamped into the Euler boxes and quaternion ellipsoids the controller
enforces, then queued as two joint-track knots (where the joint target is now,
and the posture ``duration`` seconds later, both with zero velocity), so the body
glides there and holds it. A joint track overrides Cartesian targets until
/batteur/physics/reset clears it (see services/physics/drummer.py). While a live
core's targets trail the rig clock (``PhysicsCore.target_lag``) the knots are
queued earlier on the targets' clock by the lag the core gives them, as a
streamed knot's (``PhysicsCore._stream_lag``): ``target_lag``, so the glide
starts at its rig time, unless that would cut knots streamed for rig times more
than 0.1 s before its start that are no dense stream's (an earlier posture's, a
sparse stream's waypoints): then the glide follows the last of them, at their
rig-time interval and with their lag, and plays late by the lag grown since (the
core keeps the lag it was placed with until it ends).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from common.character import N_DOF
from common.messages.physics import PhysicsPosture
from services.physics.targets import TargetError

if TYPE_CHECKING:
    from services.physics.core import PhysicsCore


def apply_posture(core: PhysicsCore, message: PhysicsPosture, lag: float = 0.0) -> float:
    """Queue ``message``'s posture on the drummer's joint track ``lag`` seconds earlier on the targets' clock (a
    live core's streamed-knot lag, ``PhysicsCore._stream_lag``: ``target_lag``, the glide starting at its rig time,
    or the lag of an earlier posture or sparse waypoints it would otherwise cut, the glide following them at their
    rig-time interval, late by the lag grown since); returns the rig time (s) the posture is asked for (``max(time,
    now) + duration``: queued ``lag`` earlier on the targets' clock); raises :class:`TargetError`."""
    from services.physics.drummer import DrummerScene

    scene = core.scene
    if not isinstance(scene, DrummerScene):
        raise TargetError("/batteur/physics/posture needs the drummer scene")
    q = np.asarray(message.values, dtype=float)
    if q.shape != (N_DOF,):
        raise TargetError(f"a posture needs {N_DOF} joint angles, got {q.size}")
    if not np.all(np.isfinite(q)):
        raise TargetError("a posture's joint angles must be finite")
    now = core.time
    start = max(float(message.time), now)  # rig time
    clamp = scene.controller.clamp_targets
    if len(scene.joint_track):
        here = scene.joint_track.sample(start - lag)[0]  # the track runs on the targets' clock
    else:
        here = scene.body.state()[0]
    zeros = np.zeros(N_DOF)
    # both knots or neither: a glide cut in half at a full queue would hold the body where it is
    scene.joint_track.check_room(start - lag, 2 if message.duration > 0 else 1)
    scene.add_joints(start, np.concatenate([clamp(np.asarray(here, dtype=float)), zeros]), now, lag)
    end = start + max(float(message.duration), 0.0)
    scene.add_joints(end, np.concatenate([clamp(q), zeros]), now, lag)
    return end
