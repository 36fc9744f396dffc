"""The sound commands run BLAS on one thread: threads cost more than they give on its small per-block products."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PROBE = ("import sys, services.sound.node, threadpoolctl; "
         "print(max(p['num_threads'] for p in threadpoolctl.threadpool_info() if p['user_api'] == 'blas'))")


def _blas_threads(env: dict[str, str]) -> int:
    run = subprocess.run([sys.executable, "-c", PROBE], cwd=ROOT, env=env, capture_output=True, text=True,
                         timeout=120, check=True)
    return int(run.stdout.split()[-1])


def test_the_sound_node_runs_blas_on_one_thread_unless_told_otherwise() -> None:
    pytest.importorskip("threadpoolctl")
    env = {k: v for k, v in os.environ.items() if not k.endswith("_NUM_THREADS")}
    # was: one thread per core, and 100+ ms blocks on a loaded machine while a china rang
    assert _blas_threads(env) == 1
    if len(os.sched_getaffinity(0)) > 1:  # OpenBLAS takes no more threads than the CPUs it may run on
        assert _blas_threads({**env, "OPENBLAS_NUM_THREADS": "2"}) == 2  # the user's choice is kept
