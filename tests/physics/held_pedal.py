"""The hi-hat pedal pressed by a left foot held still over it: what the tests of the foot's press heights read."""

from __future__ import annotations

import numpy as np

from common.kit import Kit
from services.physics.core import PhysicsCore
from services.physics.drummer import DrummerScene


def held_hihat_press(kit: Kit, above_flat_m: float, height_m: float = 1.75) -> float:
    """The hi-hat footboard's press (0 at rest, 1 flat) after 0.8 s of a ``height_m`` tall drummer's left foot
    moved (over 0.4 s) and held ``above_flat_m`` metres over the footboard pressed flat."""
    flat = np.array(kit.object("hihat_pedal").position)
    core = PhysicsCore(scene="drummer", kit=kit, pose_rate_hz=0, height_m=height_m)
    try:
        scene = core.scene
        assert isinstance(scene, DrummerScene)
        scene.add_cartesian("left_foot", 0.0, scene.current_targets()["left_foot"], np.zeros(3), 0.0)
        scene.add_cartesian("left_foot", 0.4, flat + np.array([0.0, 0.0, above_flat_m]), np.zeros(3), 0.0)
        for k in range(1, 801):
            core.step(k / 1000)
        assert scene.kit_bodies.hihat is not None and scene.kit_bodies.hihat.pedal is not None
        return scene.kit_bodies.hihat.pedal.press(core.world)
    finally:
        core.close()
