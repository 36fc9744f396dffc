"""Compile the physics kernels ahead of time: ``python -m services.physics.precompile``.

numba compiles services/physics/kernels.py on first use (about 10 s on a laptop)
and caches the result on disk (``NUMBA_CACHE_DIR``, else next to the module).
:func:`warm_up` runs a throwaway drummer for 50 ms, holding its rest posture
with Cartesian targets and control updates at 250 Hz (held torques between
them), and asks whether its targets could jump ahead (as a live core trailing
the rig clock does): that calls every kernel the physics service uses, with the
types it uses them with. The container image runs it at build time; the
physics node runs it before its real-time loop, so a cold cache costs start-up
time, never steps of a live performance (0.4 s when the cache is warm).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from services.physics.body import LIMBS
from services.physics.core import PhysicsCore
from services.physics.drummer import DrummerScene

COMPILING = "compiling the physics kernels"
"""What the physics node logs before it compiles them (``batteur rig`` looks for it in its output)."""


def kernels_cached() -> bool:
    """Whether numba has an on-disk cache for every physics kernel (False: :func:`warm_up` compiles them, about 10 s,
    minutes on a loaded machine: the first run after an install). True when it cannot tell (numba's cache internals
    moved): the node then says nothing of compiling."""
    from numba.core.registry import CPUDispatcher

    from services.physics import kernels

    caches = [getattr(f, "_cache", None) for f in vars(kernels).values() if isinstance(f, CPUDispatcher)]
    try:  # numba's internals: each cached kernel's index file, written once it is compiled
        index_files = [Path(c._cache_file._index_path) for c in caches if c is not None and hasattr(c, "_cache_file")]
    except AttributeError:
        return True
    return all(path.is_file() for path in index_files)


def warm_up() -> float:
    """Compile (or load from the cache) every physics kernel; returns the seconds it took."""
    started = time.perf_counter()
    core = PhysicsCore(scene="drummer", control_rate_hz=250.0, pose_rate_hz=0.0)
    scene = core.scene
    assert isinstance(scene, DrummerScene)
    for limb in LIMBS:
        scene.add_cartesian(limb, 0.05, scene.rest_targets[limb], np.zeros(3), 0.0)
        scene.add_cartesian(limb, 0.1, scene.rest_targets[limb], np.zeros(3), 0.0)  # held: a span to look into
    for k in range(1, 51):
        core.step(k / core.rate_hz)
    scene.can_jump(0.04, 0.07)  # what a live core trailing the rig clock asks (its look between the two times)
    core.close()
    return time.perf_counter() - started


def main(argv: Sequence[str] | None = None) -> None:
    argparse.ArgumentParser(
        prog="python -m services.physics.precompile",
        description="Compile the physics kernels (numba) into their on-disk cache, NUMBA_CACHE_DIR if set, else "
                    "next to services/physics/kernels.py, so the first physics node or render does not spend about "
                    "10 s compiling; the container image runs it at build time. With a warm cache it only loads "
                    "them. Takes no options.").parse_args(argv)
    print(f"physics kernels ready ({warm_up():.1f} s)")


if __name__ == "__main__":
    main()
