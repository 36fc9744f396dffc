"""A live drummer core whose loop comes back late at every call, its left hand streamed swaying: the driver that
tests/physics/test_live_lag_bound.py bounds and bench/live_stream_lag.py measures (shared so the figures in
docs/physics.md are the tests' own). It reads only ``PhysicsCore._streamed`` / ``_streamed_knots`` by index (rig
time s, targets' clock s), so the bench runs it against older trees too."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from common.kit import load_kit
from common.messages.physics import CartesianTarget
from services.physics.core import PhysicsCore
from services.physics.drummer import DrummerScene
from tests.physics.test_live_lag_placement import LATE_STEPS

SWAY_M, SWAY_HZ = 0.1, 2.0
"""The streamed hand's sway: metres either side of its rest, and how often."""


def swaying_target(scene: DrummerScene, t: float) -> CartesianTarget:
    """The left hand's target at rig time ``t`` s swaying ``SWAY_M`` either side of its rest at ``SWAY_HZ`` (it
    moves too fast for the targets to jump unnoticed: they trail from the first skip on)."""
    x, y, z = (float(v) for v in scene.rest_targets["left_hand"])
    w = 2 * math.pi * SWAY_HZ
    return CartesianTarget(limb="left_hand", time=t, x=x + SWAY_M * math.sin(w * t), y=y, z=z,
                           vx=SWAY_M * w * math.cos(w * t), vy=0, vz=0)


def live_core() -> PhysicsCore:
    """A live drummer core (no poses), its first 0.2 s of rig time simulated in step (close it after)."""
    core = PhysicsCore(scene="drummer", kit=load_kit("default"), pose_rate_hz=0, mode="live")
    for k in range(1, 201):
        core.step(k / 1000)
    return core


@dataclass
class StreamRun:
    """What :func:`follow_dense_stream` measured: after each call, the rig time (s), how late the streamed knot in
    use plays (s: the lag grown since it was placed; absent while none is queued) and how far the hand's target is
    from what was asked for the rig time (m); for each knot sent that cut knots sent for earlier rig times still to
    come, the rig time it cut over (s)."""

    rig: list[float] = field(default_factory=list)
    late: list[tuple[float, float]] = field(default_factory=list)
    """(rig time s, lateness s) after each call a streamed knot was in use."""
    far: list[float] = field(default_factory=list)
    cut_over: list[float] = field(default_factory=list)

    def lateness(self, since_s: float = -math.inf, until_s: float = math.inf) -> list[float]:
        """The lateness (s) after the calls at rig times in [``since_s``, ``until_s``)."""
        return [late for rig, late in self.late if since_s <= rig < until_s]


def follow_dense_stream(core: PhysicsCore, spacing_s: float, ahead_s: float, end_s: float,
                        long_skip: tuple[float, float] | None = None) -> StreamRun:
    """Step ``core`` to rig time ``end_s``, every call ``LATE_STEPS`` late, streaming the left hand before each call
    (:func:`swaying_target`): a knot every ``spacing_s`` of rig time up to ``ahead_s`` ahead; measured
    (:class:`StreamRun`). ``long_skip`` (rig time s, seconds): the first call from that rig time on comes back that
    much later still."""
    scene = core.scene
    assert isinstance(scene, DrummerScene)
    track = scene.limb_tracks["left_hand"]
    run = StreamRun()
    now_ms, k = round(core.time * 1000), 0
    sent = core.time
    while now_ms < end_s * 1000:
        sent = max(sent, now_ms / 1000)
        while sent + spacing_s <= now_ms / 1000 + ahead_s:
            sent += spacing_s
            queued = [(knot[0], knot[1]) for knot in core._streamed_knots("left_hand")]
            assert not core.handle(swaying_target(scene, sent), now_ms / 1000, "")  # accepted
            kept = {(knot[0], knot[1]) for knot in core._streamed.get("left_hand", [])}
            cut = [rig for rig, time in queued if (rig, time) not in kept and core.time < rig < sent]
            if cut:
                run.cut_over.append(sent - min(cut))
        now_ms += LATE_STEPS[k % len(LATE_STEPS)]
        if long_skip is not None and now_ms >= long_skip[0] * 1000:
            now_ms += round(long_skip[1] * 1000)
            long_skip = None
        k += 1
        core.step(now_ms / 1000)
        rig, lag = core.time, core.target_lag
        run.rig.append(rig)
        knots = core._streamed_knots("left_hand")
        if knots:
            in_use_rig, in_use_time = knots[0][0], knots[0][1]
            run.late.append((rig, lag - (in_use_rig - in_use_time)))
        asked = swaying_target(scene, rig)
        run.far.append(float(np.linalg.norm(track.sample(rig - lag)[0] - [asked.x, asked.y, asked.z])))
    return run
