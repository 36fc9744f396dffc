"""Build services/graphics/character.json from physics: the 57-DOF body the pose editor shows without physics.

Graphics may not import services/physics, so the editor's fallback body (link
names, rest pose, joint limits, effector offsets of the default 1.75 m drummer)
is a snapshot of what physics builds; ``test_poser.py`` checks it still matches.
Regenerate with ``python -m tests.graphics.character_snapshot``; ``--check`` only says how far the shipped file
is from what physics builds now (the last decimal of a few values differs between machines: no reason to rewrite).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Sequence
from pathlib import Path
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


LAST_DECIMAL = {"rest": 1e-6, "limits_deg": 1e-4, "effectors": 1e-6}
"""One unit of the last decimal :func:`build_snapshot` writes: a difference this small is rounding (the same body,
computed on another machine), not a change."""


def differences(shipped: dict[str, Any], fresh: dict[str, Any]) -> tuple[list[str], bool]:
    """What differs between two snapshots, one line per key (names and links exactly, numbers by their largest
    difference: metres or quaternion units, degrees for limits), and whether any of it is more than rounding."""
    out: list[str] = []
    changed = False
    for key in sorted(set(shipped) | set(fresh)):
        if key == "about":
            continue
        a, b = shipped.get(key), fresh.get(key)
        if key == "effectors" and isinstance(a, dict) and isinstance(b, dict) and a.keys() == b.keys():
            if any(a[k]["link"] != b[k]["link"] for k in a):
                out.append("effectors: another link")
                changed = True
                continue
            a, b = [a[k]["offset"] for k in sorted(a)], [b[k]["offset"] for k in sorted(b)]
        if isinstance(a, list) and isinstance(b, list) and a and isinstance(a[0], list):
            try:
                gap = float(np.abs(np.asarray(a, float) - np.asarray(b, float)).max())
            except ValueError:  # another shape
                out.append(f"{key}: another shape")
                changed = True
                continue
            if gap:
                rounding = gap <= 1.5 * LAST_DECIMAL.get(key, 0.0)
                out.append(f"{key}: largest difference {gap:.3g}" + (" (rounding)" if rounding else ""))
                changed = changed or not rounding
        elif a != b:
            out.append(f"{key}: differs" if isinstance(a, dict | list) else f"{key}: {a!r} -> {b!r}")
            changed = True
    return out, changed


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m tests.graphics.character_snapshot",
        description="Rebuild services/graphics/character.json (the pose editor's body when physics is not running) "
                    "from the physics drummer (PhysicsCore scene=drummer, default settings). tests/graphics/"
                    "test_poser.py checks the shipped file against physics, with tolerances: rebuild it when that "
                    "test fails after a change to the body.")
    parser.add_argument("--check", action="store_true",
                        help="write nothing: print how the shipped file (or --output) differs from what physics "
                             "builds now; exit 1 if by more than rounding (a unit of the last decimal written)")
    parser.add_argument("-o", "--output", type=Path, default=SNAPSHOT, metavar="FILE",
                        help="where to write (default: services/graphics/character.json)")
    opts = parser.parse_args(argv)
    fresh = build_snapshot()
    if opts.check:
        found, changed = differences(json.loads(opts.output.read_text(encoding="utf-8")), fresh)
        print("\n".join(found) if found else f"{opts.output} is what physics builds")
        return 1 if changed else 0
    opts.output.write_text(dumps(fresh), encoding="utf-8")
    print(f"wrote {opts.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
