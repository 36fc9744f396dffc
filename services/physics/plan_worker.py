"""Where the live physics node computes score plans: a thread, or a process of its own at lower priority.

The gesture planner is Python and NumPy; in a thread it takes turns with the 1 kHz loop for the interpreter's
lock (re-planning a 55 s score: 47-147 ms gaps in the loop), in a process it only takes the CPU the loop leaves
(15-37 ms; docs/physics.md, "Background plans"). Either can be stopped without waiting for the plan in flight.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
from concurrent.futures import Executor, ProcessPoolExecutor, ThreadPoolExecutor
from typing import Literal

PLANNER_NICE = 10
"""Niceness added to a planning process: sharing a core, the physics loop gets about nine tenths of it (the
scheduler's weights for nice 0 and 10); the planner still takes whatever the loop leaves."""

PlanWorker = Literal["thread", "process"]
"""Where background plans run: a thread of the node (shares the interpreter with the physics loop) or a process
of their own (another core, or the OS's scheduling, instead of the interpreter's lock)."""


def _start_planner_process() -> None:
    """A planning process's start: lower priority than the loop, Ctrl-C left to the node (which stops it), the
    gesture database loaded now."""
    from common.gesture.database import default_database

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        os.nice(PLANNER_NICE)
    except (AttributeError, OSError):  # not on this system: plans at the loop's priority
        pass
    default_database()


def plan_executor(worker: PlanWorker) -> Executor:
    """A one-worker executor of the kind ``worker``; a process is started (and its database loaded) at once."""
    if worker == "thread":
        return ThreadPoolExecutor(1, thread_name_prefix="physics-plan")
    pool = ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn"),
                               initializer=_start_planner_process)
    pool.submit(int)  # starts the process (and loads the database) now, not with the first plan
    return pool


def stop_executor(pool: Executor) -> None:
    """Stop a planning worker without waiting for the plan in flight (a process is terminated)."""
    pool.shutdown(wait=False, cancel_futures=True)
    processes = getattr(pool, "_processes", None) or {}  # no public way to stop them before Python 3.14
    for process in list(processes.values()):
        process.terminate()
