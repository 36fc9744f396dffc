"""What a planning process and the physics node import to start: none of the heavy modules their start does not use.

Each planning process (the node's first, its spare, one after every abandoned plan) and the node itself paid about
0.4 s of CPU at start for ``scipy.signal`` and the ``scipy.stats`` it brings: the gesture database imported
``find_peaks`` at module level, which only a user capture without contact frames needs (every shipped unit names
its own). A planning process imports the planner only, never the physics kernels (numba) or PyBullet
(services/physics/plan_worker.py).
"""

from __future__ import annotations

import functools
import subprocess
import sys

import pytest

from services.physics.plan_worker import PlanWorkers

pytestmark = pytest.mark.timeout(180)

NOT_AT_START = ("scipy.signal", "scipy.stats", "matplotlib")
"""Modules neither a planning process nor the physics node needs to start."""

NOT_IN_A_PLANNER = (*NOT_AT_START, "numba", "pybullet", "services.physics.score_player")
"""... nor a planning process at all (the physics kernels and the simulator are the node's)."""

LOADED = "sorted(m for m in __import__('sys').modules if m in {names!r})"
"""An expression naming which of ``names`` the interpreter evaluating it has imported."""


def test_a_loaded_planning_process_has_imported_no_heavy_module_it_does_not_use() -> None:
    workers = PlanWorkers("process")
    try:
        assert workers.wait_loaded(120.0) and workers.load_error is None
        # eval, not a function of this module: the process would import this module (and pytest) to run that
        loaded = workers.submit(functools.partial(eval, LOADED.format(names=set(NOT_IN_A_PLANNER)))).result(120.0)
    finally:
        workers.close()
    assert loaded == []


def test_the_physics_nodes_module_imports_no_heavy_module_its_start_does_not_use() -> None:
    code = f"import services.physics.node; print({LOADED.format(names=set(NOT_AT_START))})"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120).stdout
    assert out.strip() == "[]"
