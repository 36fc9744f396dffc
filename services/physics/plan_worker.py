"""Where the live physics node computes score plans: a thread, or a process of its own at lower priority.

The gesture planner is Python and NumPy; in a thread it takes turns with the 1 kHz loop for the interpreter's
lock (re-planning a 55 s score: 47-147 ms gaps in the loop), in a process it only takes the CPU the loop leaves
(15-37 ms; docs/physics.md, "Background plans"). Either can be stopped without waiting for the plan in flight.

A plan dropped while it is computed (a reset) is abandoned (:meth:`PlanWorkers.abandon`): its process is
terminated and a spare process, started and loaded beforehand, plans the next one at once (a new process takes
2-5 s to import the planner and load the gesture database, several times a 439-note plan); a thread cannot be
stopped, so it finishes the dropped plan alone while a new thread plans the next.

Start: the node starts its first process before it builds its scene (the load overlaps the node's own start) and
says it is up only once that process has loaded (:meth:`PlanWorkers.wait_loaded`): a node that said it was up
while both its processes still loaded kept its first plans waiting 15-36 s under load, and the notes sent meanwhile
were refused as late. The spare starts only once a plan has been computed (:meth:`PlanWorkers.idle`), so the two do
not share the CPU at start. While the current worker still loads (:attr:`PlanWorkers.loading`: a process started
after an abandon with no spare left), the score player refuses live notes at once rather than plan them late.
"""

from __future__ import annotations

import contextlib
import ctypes
import logging
import multiprocessing
import os
import signal
import sys
import threading
import time
import traceback
from collections.abc import Callable, Iterator, Mapping
from concurrent.futures import BrokenExecutor, Executor, Future, ProcessPoolExecutor, ThreadPoolExecutor
from concurrent.futures import wait as wait_futures
from typing import TYPE_CHECKING, Any, Literal, TypeVar

from common.score.limbs import STATURE_M

if TYPE_CHECKING:
    import numpy as np

    from common.gesture.plan import GesturePlan, Grip, Nuance
    from common.kit import Kit, Limb
    from common.score.events import DrumEvent
    from common.score.hands import HandAlgorithm, Sticking
    from common.score.limbs import LimbLengths

log = logging.getLogger("batteur.physics.score")

T = TypeVar("T")

PLANNER_NICE = 10
"""Niceness added to a planning process: sharing a core, the physics loop gets about nine tenths of it (the
scheduler's weights for nice 0 and 10); the planner still takes whatever the loop leaves. On a core busy with other
nice-0 processes that is little: the 439-note rock groove (0.54 s alone) planned in 23-27 s against 4 busy ones, 6.5-6.8
s at nice 5, 2.7-3.1 s at nice 0 (7 Dec, one core; docs/physics.md "Background plans"). Kept at 10 until the loop's
timing at nice 5 is measured too."""

PlanWorker = Literal["thread", "process"]
"""Where background plans run: a thread of the node (shares the interpreter with the physics loop) or a process
of their own (another core, or the OS's scheduling, instead of the interpreter's lock)."""


class PlanError(ValueError):
    """Events the planner cannot plan (the message says why): the score player refuses the message that asked."""


def plan_events(events: list[DrumEvent], beats: np.ndarray, lead_in: float, kit: Kit, algorithm: HandAlgorithm,
                sticking: Sticking, grip: Grip, nuance: Nuance, height_m: float = STATURE_M,
                lengths: LimbLengths | None = None, last_strokes: Mapping[Limb, float] | None = None
                ) -> GesturePlan:
    """Distribute and plan rig-timed events (the planner's times are rig seconds); raises :class:`PlanError`.

    ``height_m``: the drummer's height, metres (the node's ``--height-m``): the reach its notes are checked
    against (``distribute``'s ``unreachable`` flags); ``lengths``: the arms and legs of a body built from a
    skeleton (the node's ``--skeleton-bvh``), None: the height's; ``last_strokes``: each foot's last note played
    before these, rig seconds (a kick foot's first stroke is made from rest only long enough after it:
    ``plan_gestures``). Here, not in the score player, so that a planning process imports the planner only (the
    score player's module brings the physics kernels: 1.8 s more to start a process)."""
    from common.gesture.planner import PlannerConfig, plan_gestures
    from common.score.events import Score
    from common.score.limbs import distribute

    score = Score(events=events, beats=beats, source="performance")
    assignment = distribute(score, kit, algorithm, sticking, height_m=height_m, lengths=lengths)
    if not assignment.notes:
        raise PlanError("nothing to play: the kit has none of these notes' instruments")
    config = PlannerConfig(grip=grip, nuance=nuance, lead_in=max(lead_in, 0.05))
    try:
        return plan_gestures(assignment, kit, score, config, last_strokes=last_strokes)
    except Exception as exc:  # a planner failure rejects this message; it never stops the service
        log.exception("the gesture planner failed")
        raise PlanError(f"the gesture planner failed: {type(exc).__name__}: {exc}") from None


PR_SET_PDEATHSIG = 1
"""Linux prctl option: the signal this process gets when its parent dies."""


def _die_with(parent: int) -> None:
    """Linux: terminate this process when the node (``parent``, its pid) dies without closing it (killed,
    crashed): an idle planning process, waiting for work, did not notice the node gone and lived on (120 MB
    each, for good). Elsewhere nothing (the node's close still stops it)."""
    if not sys.platform.startswith("linux"):
        return
    try:
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
    except (OSError, AttributeError):  # no prctl here
        return
    if os.getppid() != parent:  # the node died before the call
        os._exit(0)


def _lower_priority() -> None:
    """This process at :data:`PLANNER_NICE` below the loop's priority (where the system allows it)."""
    try:
        os.nice(PLANNER_NICE)
    except (AttributeError, OSError):  # not on this system: plans at the loop's priority
        pass


def _start_planner_process(parent: int, niced: bool) -> None:
    """A planning process's start: it dies with the node (``parent``, its pid), Ctrl-C left to the node (which
    stops it); ``niced``: at lower priority than the loop from now on (else after its load:
    :func:`_load_planner_process`)."""
    _die_with(parent)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if niced:
        _lower_priority()


def load_planner() -> None:
    """Import the planner and load the gesture database: in a new process 2-5 s of CPU (the first task of each
    worker; in the node, where they are loaded already, nothing). A test may replace it for a thread worker (a
    load that takes as long as the test wants)."""
    import common.gesture.planner  # noqa: F401 - imported now, not with the first plan
    import common.score.limbs  # noqa: F401
    from common.gesture.database import default_database

    default_database()


def _load_planner_process(nice_after: bool) -> None:
    """A planning process's first task: :func:`load_planner`, then (``nice_after``) its lower priority. A load that
    fails (an import error, a broken database) ends the process: its pool is then broken, and the node plans in a
    thread of its own (:meth:`PlanWorkers.submit`), as when a process dies; a process left standing would fail every
    plan with the same error."""
    try:
        load_planner()
    except BaseException:
        traceback.print_exc()  # on the node's stderr: why its planning process stopped
        sys.stderr.flush()
        os._exit(1)
    if nice_after:
        _lower_priority()


def plan_executor(worker: PlanWorker, first: bool = False) -> tuple[Executor, Future[None]]:
    """A one-worker executor of the kind ``worker``, its load (:func:`load_planner`) submitted now as its first
    task, and that task's future: done once the worker can plan at once (a cheap round-trip after the load).

    A process is started now; ``first``: the node's first, started before its loop runs, loads at the node's
    priority and only then lowers its own (niced from its start, it loaded in 15-36 s instead of 2-5 s while the
    node built its scene on the same core under load); any later one (a spare, a replacement, while the loop runs)
    is niced before it loads."""
    if worker == "thread":
        thread_pool = ThreadPoolExecutor(1, thread_name_prefix="physics-plan")
        return thread_pool, thread_pool.submit(load_planner)
    # started by the calling thread, whose end the child takes for its parent's (PR_SET_PDEATHSIG): the node's
    # loop thread (or the main thread), which lasts as long as the node
    pool: ProcessPoolExecutor | None = None
    try:
        with _stop_signals_held():
            pool = ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn"),
                                       initializer=_start_planner_process, initargs=(os.getpid(), not first))
            loaded = pool.submit(_load_planner_process, first)  # starts the process and its load now
    except BaseException:  # a node stopped while starting (common.runtime.StoppedWhileStarting): none left behind
        if pool is not None:
            stop_executor(pool, STOP_WAIT_S)
        raise
    return pool, loaded


@contextlib.contextmanager
def _stop_signals_held() -> Iterator[None]:
    """SIGINT and SIGTERM wait for the end of the block, then go to their handler (main thread only): a node's
    stop raised inside a process pool's start (common.runtime.StoppedWhileStarting) could leave a process the pool
    does not know of, which printed a traceback (its start data cut short) or which the interpreter waited for
    at exit."""
    stops = (signal.SIGINT, signal.SIGTERM)
    if threading.current_thread() is not threading.main_thread() or any(signal.getsignal(s) is None for s in stops):
        yield  # no Python handler to hold (or to put back)
        return
    held: list[int] = []
    previous = {sig: signal.signal(sig, lambda signum, _frame: held.append(signum)) for sig in stops}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        if held:
            signal.raise_signal(held[0])


STOP_WAIT_S = 5.0
"""Longest :meth:`PlanWorkers.close` waits for a process pool's own thread to end once its process is terminated,
seconds (it ends within milliseconds of the process)."""


def stop_executor(pool: Executor, wait_s: float = 0.0) -> None:
    """Stop a planning worker without waiting for the plan in flight (a process is terminated; the executor's
    own thread reaps it). ``wait_s`` > 0: then wait up to that many seconds for that thread to end (a node closing
    for good: Python 3.11's exit hook wakes a pool thread still running, and one closing its pipe at that moment
    printed "Exception ignored ... OSError: [Errno 9] Bad file descriptor" after a start error, 1 run in 2-6)."""
    # no public way to stop them before Python 3.14; taken before shutdown, which forgets them
    processes = list((getattr(pool, "_processes", None) or {}).values())
    manager: threading.Thread | None = getattr(pool, "_executor_manager_thread", None)
    pool.shutdown(wait=False, cancel_futures=True)
    for process in processes:
        process.terminate()
    if wait_s > 0 and manager is not None:
        manager.join(wait_s)


class PlanWorkers:
    """The node's planning worker, one plan at a time, and for a process a spare started once a plan has been
    computed (see the module docstring). ``worker``: a process (the node) or a thread (tests, benchmarks). The first
    worker starts (and begins its load) at once: :meth:`wait_loaded` waits for it."""

    def __init__(self, worker: PlanWorker = "process") -> None:
        self.kind: PlanWorker = worker
        self._current, self._loaded = plan_executor(worker, first=True)
        self._loading_since = time.monotonic()
        """When the current worker started its load (``time.monotonic()``, s)."""
        self._spare: Executor | None = None
        """A process started (database loaded) beforehand, for the plan after an abandoned one; started by
        :meth:`idle` once a plan has been computed, not with the first (they shared the CPU at start)."""
        self._spare_loaded: Future[None] | None = None
        self._spare_since = 0.0
        self._closed = False
        self._last: Future[Any] | None = None
        """The latest plan submitted since the last :meth:`abandon` (None: none yet)."""

    @property
    def loading(self) -> bool:
        """The current worker still loads the planner: a plan submitted now would wait for that (seconds)."""
        return not self._loaded.done()

    @property
    def loading_s(self) -> float:
        """Seconds the current worker has been loading (or took to load) since it started."""
        return time.monotonic() - self._loading_since

    def wait_loaded(self, timeout_s: float | None = None) -> bool:
        """Block until the current worker has loaded the planner (the node, before it says it is up); True if it
        has (or its load failed: :attr:`load_error`; :meth:`submit` then plans in a thread), False after
        ``timeout_s`` seconds."""
        done, _ = wait_futures([self._loaded], timeout=timeout_s)
        return bool(done)

    @property
    def load_error(self) -> BaseException | None:
        """Why the current worker's load failed (its process stopped: a broken pool), None while it loads or once
        it has loaded."""
        if not self._loaded.done() or self._loaded.cancelled():
            return None
        return self._loaded.exception()

    def submit(self, plan: Callable[[], T]) -> Future[T]:
        """Compute ``plan()`` in the worker, after the plans submitted before it. A planning process that died
        (killed, out of memory) is replaced by a thread of the node (logged), for good."""
        try:
            future = self._current.submit(plan)
        except BrokenExecutor as exc:
            log.error("the planning process stopped (%s): planning in a thread of the node from now on", exc)
            self._stop()
            self.kind = "thread"
            self._current, self._loaded = plan_executor("thread")
            self._loading_since = time.monotonic()
            future = self._current.submit(plan)
        self._last = future
        return future

    def abandon(self) -> None:
        """Stop computing the plans submitted so far, without waiting (their futures are never to be read):
        a process is terminated and the spare takes its place (a new spare starts at the next :meth:`idle`; with
        none left, a new process starts now: :attr:`loading` until it has loaded); a thread is left to finish
        alone and a new one plans from now on."""
        old, self._last = self._current, None
        if self._spare is not None and self._spare_loaded is not None:
            self._current, self._loaded, self._loading_since = self._spare, self._spare_loaded, self._spare_since
            self._spare, self._spare_loaded = None, None
        else:
            self._current, self._loaded = plan_executor(self.kind)
            self._loading_since = time.monotonic()
        stop_executor(old)

    @property
    def stops_at_once(self) -> bool:
        """:meth:`abandon` would leave a worker ready to plan at once: a thread (a new one), or a process with its
        spare loaded (without one, a new process would load for seconds: a plan after it would be refused
        meanwhile)."""
        if self.kind == "thread":
            return True
        loaded = self._spare_loaded
        return loaded is not None and loaded.done() and not loaded.cancelled() and loaded.exception() is None

    def idle(self) -> None:
        """No plan in flight: start the spare a process worker lacks (at start, or after :meth:`abandon`) once a
        plan has been computed since. Not earlier: on a shared core its start (2-5 s of CPU) took turns with the
        plan after the abandoned one (0.04 s alone, 0.2-0.3 s with it), and at the node's start with the first
        process's load."""
        last = self._last
        if self._spare is None and last is not None and last.done() and self.kind == "process" and not self._closed:
            self._spare, self._spare_loaded = plan_executor("process")
            self._spare_since = time.monotonic()

    def close(self) -> None:
        """Stop every worker without waiting for the plan in flight (processes terminated, their pools' threads
        waited for: :data:`STOP_WAIT_S`); for good."""
        self._closed = True
        self._stop(STOP_WAIT_S)

    def _stop(self, wait_s: float = 0.0) -> None:
        for pool in (self._current, self._spare):
            if pool is not None:
                stop_executor(pool, wait_s)
        self._spare, self._spare_loaded = None, None
