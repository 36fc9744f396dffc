"""The drummer's body as built, for a researcher: ``batteur physics --show-body`` and the node's start line.

What the scene built from the height, mass and ``--skeleton-bvh`` (services/physics/anthropometry.py), the
generated model (services/physics/character.py), the controller's gains (services/physics/control.py) and the joint
limits' sources (services/physics/limits.py): read from the scene, never recomputed.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

from services.physics.anthropometry import body_mass_of
from services.physics.character import JOINTS

if TYPE_CHECKING:
    from services.physics.drummer import DrummerScene

PAIRED = ("clavicle", "upper_arm", "forearm", "hand", "thigh", "shank", "foot")
"""Segments the body has two of (one per side); the table gives one side's."""


def body_json(scene: DrummerScene) -> dict[str, Any]:
    """The body as built: height m, mass kg (asked, and the segments' sum), DOF count, per segment (one side of
    a pair) length m, mass kg and count, per joint the torque limit N m, the explicit PD's gains per DOF (ks
    N m/rad, kd N m s/rad: ``joint_pd``, ``cartesian_pd``), its limits' source and whether a quaternion ellipsoid
    (Algorithm 1) holds it besides its Euler box, and the box, degrees."""
    anthro = scene.anthro
    controller = scene.controller
    limits = scene.limits
    torque = scene.model.torque_limits
    segments = {name: {"length_m": round(seg.length_m, 4), "mass_kg": round(seg.mass_kg, 3),
                       "count": 2 if name in PAIRED else 1} for name, seg in anthro.segments.items()}
    joints: dict[str, Any] = {}
    for k, joint in enumerate(JOINTS):
        dofs = range(3 * k, 3 * k + 3)
        joints[joint] = {
            "torque_limit_nm": round(torque[f"{joint}_x"], 2),
            "ks_nm_per_rad": [round(float(controller.ks[i]), 2) for i in dofs],
            "kd_nms_per_rad": [round(float(controller.kd[i]), 3) for i in dofs],
            "limits_source": limits.sources.get(joint, "?"),
            "quaternion_limit": joint in limits.quaternion,
            "box_deg": [[round(math.degrees(float(scene.body.lower[i])), 1),
                         round(math.degrees(float(scene.body.upper[i])), 1)] for i in dofs],
        }
    unit, why = skeleton_unit(scene)
    return {"height_m": scene.settings.height_m, "mass_kg": scene.settings.mass_kg,
            "segments_mass_kg": round(body_mass_of(anthro), 2), "dof": len(scene.model.dof_names),
            "control_rate_hz": scene.settings.rate_hz / scene.control_every,
            "skeleton_bvh": scene.settings.skeleton_bvh, "skeleton_unit": unit, "skeleton_unit_why": why,
            "limits_from": list(scene.settings.limits_from) or "default",
            "limits_symmetric": limits.symmetric,
            "segments": segments, "joints": joints,
            "gains": f"explicit PD at {controller.params.frequency_hz:g} Hz (per DOF, scaled by its inertia); the "
                     f"computed-torque modes (cartesian, joint_ct) use {controller.params.ct_frequency_hz:g} Hz "
                     f"(trunk {controller.params.trunk_ct_frequency_hz:g} Hz) through the mass matrix"}


def skeleton_unit(scene: DrummerScene) -> tuple[str | None, str | None]:
    """The unit the scene's ``skeleton_bvh`` was read in (a key of ``METRES_PER_SKELETON_UNIT``: "cm") and why
    ("as given", or the guess's reason), as the scene read it (the same file, the same ``skeleton_units``); (None,
    None) without a skeleton. A length read in the wrong unit builds a giant or a dwarf: the file alone did not say
    which (until the day after 7 Dec)."""
    if not scene.settings.skeleton_bvh:
        return None, None
    from services.physics.bvh_motion import read_skeleton  # the BVH reader: only with a skeleton

    reading = read_skeleton(scene.settings.skeleton_bvh, scene.settings.skeleton_units)
    return reading.unit, reading.why


def body_text(scene: DrummerScene) -> str:
    """:func:`body_json` as two tables (units in every column header)."""
    from services.physics.bvh_motion import UNIT_WORDS

    data = body_json(scene)
    skeleton = data["skeleton_bvh"] or "de Leva table"
    if data["skeleton_unit"] is not None:
        skeleton += f" (read in {UNIT_WORDS[data['skeleton_unit']]}: {data['skeleton_unit_why']})"
    lines = [f"drummer {data['height_m']:g} m, {data['mass_kg']:g} kg asked; segments {data['segments_mass_kg']:g} kg "
             f"in all; {data['dof']} DOF (19 joints x 3); skeleton: {skeleton}; "
             f"limits from: {', '.join(data['limits_from']) if isinstance(data['limits_from'], list) else 'default'}"
             f" ({'mirror-symmetric' if data['limits_symmetric'] else 'each side its own: --asymmetric-limits'})",
             control_rate_text(scene), "",
             f"{'segment':<10} {'count':>5} {'length m':>9} {'mass kg':>8}"]
    for name, seg in data["segments"].items():
        lines.append(f"{name:<10} {seg['count']:>5} {seg['length_m']:>9.3f} {seg['mass_kg']:>8.2f}")
    lines += ["", f"{data['gains']}", "",
              f"{'joint':<15} {'torque N m':>10} {'ks x/y/z N m/rad':>24} {'kd x/y/z N m s/rad':>21} "
              f"{'box x/y/z deg':>40}  limits source"]
    for joint, row in data["joints"].items():
        ks = "/".join(f"{v:.0f}" for v in row["ks_nm_per_rad"])
        kd = "/".join(f"{v:.2f}" for v in row["kd_nms_per_rad"])
        box = " ".join(f"[{lo:g},{hi:g}]" for lo, hi in row["box_deg"])
        source = row["limits_source"] + (" (box + quaternion ellipsoid)" if row["quaternion_limit"] else " (box)")
        lines.append(f"{joint:<15} {row['torque_limit_nm']:>10.1f} {ks:>24} {kd:>21} {box:>40}  {source}")
    return "\n".join(lines)


def body_summary(scene: DrummerScene) -> str:
    """One line for the node's start log: height, mass, DOF, and the ellipsoids."""
    data = body_json(scene)
    ellipsoids = sum(1 for row in data["joints"].values() if row["quaternion_limit"])
    return (f"drummer body: {data['height_m']:g} m, {data['mass_kg']:g} kg ({data['segments_mass_kg']:g} kg of "
            f"segments), {data['dof']} DOF, {ellipsoids} of {len(JOINTS)} joints with a quaternion limit; "
            f"{control_rate_text(scene)} (batteur physics --show-body: the whole body)")


def control_rate_text(scene: DrummerScene) -> str:
    """The full control updates' real rate: a whole number of physics steps apart, so ``--control-rate-hz`` 300 at
    1 kHz updates every 3 steps, 333.3 Hz (said with what was asked when they differ)."""
    steps_hz = scene.settings.rate_hz
    asked = scene.settings.control_rate_hz
    real = steps_hz / scene.control_every
    said = f"control updates at {real:.4g} Hz (every {scene.control_every} of the {steps_hz:g} Hz physics steps"
    return said + (f"; {asked:g} Hz asked)" if abs(real - asked) > 1e-6 * asked else ")")
