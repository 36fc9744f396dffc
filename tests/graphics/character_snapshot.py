"""Build services/graphics/character.json from physics: the 57-DOF body the pose editor shows without physics.

Graphics may not import services/physics, so the editor's fallback body (link
names, rest pose, joint limits, effector offsets of the default 1.75 m drummer)
is a snapshot of what physics builds; ``test_poser.py`` checks it still matches.
Regenerate with ``python -m tests.graphics.character_snapshot``.
"""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from services.graphics.poser import SNAPSHOT


def build_snapshot() -> dict[str, Any]:
    from services.physics.body import LIMBS
    from services.physics.core import PhysicsCore

    core = PhysicsCore(scene="drummer")
    try:
        scene = core.scene
        body = scene.body  # type: ignore[attr-defined]
        names = [n for n in core.names if not n.startswith("kit.")]
        pose = np.asarray(core.pose().values).reshape(-1, 7)[: len(names)]
        effectors: dict[str, dict[str, Any]] = {}
        for limb in LIMBS:
            link = f"{limb.split('_')[0]}_stick" if limb.endswith("hand") else limb
            pos, quat = body.link_pose(body.link_index[link])
            tip, _ = body.link_pose(body.tip_links[limb])
            offset = Rotation.from_quat(quat).inv().apply(tip - pos)
            effectors[limb] = {"link": link, "offset": [round(float(v), 6) for v in offset]}
        return {
            "about": "the physics drummer (PhysicsCore scene=drummer, default settings) for the pose editor; "
                     "regenerate: python -m tests.graphics.character_snapshot",
            "height_m": core.settings.height_m,
            "names": names,
            "rest": [[round(float(v), 6) for v in row] for row in pose],
            "limits_deg": [[round(math.degrees(lo), 4), round(math.degrees(hi), 4)]
                           for lo, hi in zip(body.lower, body.upper, strict=True)],
            "effectors": effectors,
        }
    finally:
        core.close()


def dumps(snapshot: dict[str, Any]) -> str:
    """JSON with one link, one DOF or one effector per line."""
    lines = []
    for key, value in snapshot.items():
        if isinstance(value, list) and value and isinstance(value[0], list):
            rows = ",\n  ".join(json.dumps(row) for row in value)
            lines.append(f'"{key}": [\n  {rows}\n ]')
        elif isinstance(value, dict):
            rows = ",\n  ".join(f"{json.dumps(k)}: {json.dumps(v)}" for k, v in value.items())
            lines.append(f'"{key}": {{\n  {rows}\n }}')
        else:
            lines.append(f"{json.dumps(key)}: {json.dumps(value)}")
    return "{\n " + ",\n ".join(lines) + "\n}\n"


if __name__ == "__main__":
    SNAPSHOT.write_text(dumps(build_snapshot()), encoding="utf-8")
    print(f"wrote {SNAPSHOT}")
