"""Physics' own link frames (its Pose message) for joint angles a test chooses: the drummer's body set to each frame's
angles, no simulation, as a :class:`PoseSequence` at 60 Hz (the BVH and glTF export tests)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from common.character import JOINTS
from services.graphics.sequence import PoseSequence


def posed_frames(frames: Sequence[Mapping[str, tuple[float, float, float]]]) -> PoseSequence:
    """One pose per mapping of joint name (``common.character.JOINTS``, e.g. ``"seat"``, ``"left_hip"``) to its
    three angles, degrees; joints not named keep their rest angles. Shape: (len(frames), links, 7)."""
    from services.physics.core import PhysicsCore
    from services.physics.drummer import DrummerScene

    core = PhysicsCore(scene="drummer", pose_rate_hz=50.0)
    try:
        scene = core.scene
        assert isinstance(scene, DrummerScene)
        body = scene.body
        rest = body.state()[0].copy()
        values = []
        for angles in frames:
            q = rest.copy()
            for joint, degrees in angles.items():
                k = 3 * JOINTS.index(joint)
                q[k:k + 3] = np.radians(degrees)
            body.set_state(q)
            values.append(np.array(core.pose().values).reshape(-1, 7))
        names = list(core.names)
    finally:
        core.close()
    return PoseSequence(names, np.arange(len(values)) / 60.0, np.stack(values))
