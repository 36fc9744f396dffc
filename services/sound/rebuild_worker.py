"""The live node's rebuild worker: daemon threads, one per lane (an instrument), that compute parameter changes
in order within a lane and side by side across lanes (a 20,000-mode snare no longer holds up the kick's radius
change for seconds), and can be abandoned at once.

A ``ThreadPoolExecutor`` cannot be abandoned: the interpreter joins its threads at exit, so stopping the node
waited for a rebuild in flight (a 20,000-mode change: seconds, and its child interpreter ran on). This worker's
thread is a daemon (nothing waits for it), :meth:`RebuildWorker.close` cancels the jobs not started and kills the
child interpreters the running one started (:func:`run_child`), and whatever the running job returns is dropped.
"""

from __future__ import annotations

import queue
import subprocess
import threading
from collections.abc import Callable
from concurrent.futures import Future
from typing import Any, TypeVar

T = TypeVar("T")


class Abandoned(Exception):  # noqa: N818 - the job was abandoned, not an error of its own
    """Raised in a job whose worker was closed (its child interpreter killed): the result is not wanted."""


class ChildProcesses:
    """The child interpreters started by one worker's jobs, killed together by :meth:`close`."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._running: set[subprocess.Popen[bytes]] = set()
        self.closed = False

    def run(self, args: list[str], timeout_s: float) -> bytes:
        """Run ``args`` to the end and return its standard output; :class:`Abandoned` if :meth:`close` was called
        before or meanwhile, ``subprocess.CalledProcessError`` / ``TimeoutExpired`` as ``subprocess.run``."""
        with self._lock:  # started under the lock, so close() either sees it or prevents it
            if self.closed:
                raise Abandoned
            child = subprocess.Popen(args, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE)
            self._running.add(child)
        try:
            try:
                out, err = child.communicate(timeout=timeout_s)
            except subprocess.TimeoutExpired:
                child.kill()
                child.communicate()
                raise
        finally:
            with self._lock:
                self._running.discard(child)
        if self.closed:
            raise Abandoned
        if child.returncode != 0:
            raise subprocess.CalledProcessError(child.returncode, args, out, err)
        return out

    def close(self) -> None:
        """Kill every child running now, and refuse new ones."""
        with self._lock:
            self.closed = True
            for child in self._running:
                child.kill()  # its job's communicate() returns and raises Abandoned


_current = threading.local()


def run_child(args: list[str], timeout_s: float) -> bytes:
    """Run a child interpreter for the current job: one a :class:`RebuildWorker`'s close kills when called from
    its thread, else a plain ``subprocess.run`` (same errors as :meth:`ChildProcesses.run`)."""
    children: ChildProcesses | None = getattr(_current, "children", None)
    if children is not None:
        return children.run(args, timeout_s)
    return subprocess.run(args, stdin=subprocess.DEVNULL, capture_output=True, check=True, timeout=timeout_s).stdout


def abandoned() -> bool:
    """True in a job whose worker was closed (a job may stop early: its result is dropped)."""
    children: ChildProcesses | None = getattr(_current, "children", None)
    return children is not None and children.closed


class RebuildWorker:
    """Runs submitted calls in daemon threads, one per lane (started at the lane's first call): the calls of one
    lane one after another, in submission order; those of different lanes at the same time."""

    def __init__(self, name: str = "sound-rebuild") -> None:
        self.name = name
        self.children = ChildProcesses()
        self._lanes: dict[str, queue.SimpleQueue[tuple[Future[Any], Callable[..., Any], tuple[Any, ...]] | None]] = {}
        self._lock = threading.Lock()

    def submit(self, fn: Callable[..., T], *args: Any, lane: str = "") -> Future[T]:
        """Queue ``fn(*args)`` on ``lane`` (after that lane's earlier calls); its Future completes in the lane's
        thread. RuntimeError once closed."""
        future: Future[T] = Future()
        with self._lock:
            if self.children.closed:
                raise RuntimeError("the rebuild worker is closed")
            jobs = self._lanes.get(lane)
            if jobs is None:
                jobs = self._lanes[lane] = queue.SimpleQueue()
                thread_name = f"{self.name}-{lane}" if lane else self.name
                threading.Thread(target=self._run, args=(jobs,), name=thread_name, daemon=True).start()
            jobs.put((future, fn, args))
        return future

    def _run(self, jobs: queue.SimpleQueue[tuple[Future[Any], Callable[..., Any], tuple[Any, ...]] | None]) -> None:
        _current.children = self.children
        while True:
            job = jobs.get()
            if job is None or self.children.closed:
                return
            future, fn, args = job
            if not future.set_running_or_notify_cancel():
                continue
            try:
                result = fn(*args)
            except BaseException as exc:  # noqa: BLE001 - handed to whoever reads the Future
                future.set_exception(exc)
            else:
                future.set_result(result)

    def close(self) -> None:
        """Abandon every job: those waiting are cancelled, the running ones' children killed and their results
        dropped. Returns at once (nothing is joined). Idempotent."""
        with self._lock:
            self.children.close()
            for jobs in self._lanes.values():
                while True:
                    try:
                        job = jobs.get_nowait()
                    except queue.Empty:
                        break
                    if job is not None:
                        job[0].cancel()
                jobs.put(None)  # wakes an idle thread so it ends
