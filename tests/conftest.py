"""Shared pytest setup: the network-namespace lab fixture for tests that need real networking, physics' strike
scene core (``strike_core``), one glTF render of the tiny score (``tiny_gltf_render``), a per-run user
configuration folder, and the programs and multiprocessing children tests start ending with the run (a run stopped
by SIGTERM or SIGKILL left its node processes running: nine graphics nodes loaded a machine after one)."""

import contextlib
import ctypes
import multiprocessing.util
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from types import FrameType
from typing import Any

import pytest

from tests.netns import netns_lab  # noqa: F401  (fixture)

_CONFIG_HOME: str | None = None

PR_SET_PDEATHSIG = 1
"""Linux prctl option: the signal a process gets when the thread that started it ends."""
_POPEN_INIT = subprocess.Popen.__init__
"""``subprocess.Popen.__init__`` as the standard library has it (restored at the end of the run)."""
_SPAWNV_PASSFDS = multiprocessing.util.spawnv_passfds
"""``multiprocessing.util.spawnv_passfds`` as the standard library has it (restored at the end of the run)."""
_FORK_EXEC_PREEXEC_FN = 21
"""Position of ``preexec_fn`` in ``_posixsubprocess.fork_exec``'s arguments (CPython 3.11 to 3.13)."""
FORK_EXEC_KNOWN = {(3, 11), (3, 12), (3, 13)}
"""The CPython versions whose ``fork_exec`` has ``preexec_fn`` at :data:`_FORK_EXEC_PREEXEC_FN` (a private
function: on others multiprocessing's children are not armed)."""


def _prctl() -> Callable[..., int] | None:
    """libc's prctl, looked up in the test process (the child only calls it: nothing to import or load after a fork),
    or None off Linux."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        prctl: Callable[..., int] = ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return None
    return prctl


def _arm_child(prctl: Callable[..., int], parent_pid: int, then: Callable[[], object] | None) -> Callable[[], None]:
    """What a child started by a test runs before its program: SIGTERM when the test process ends (even by SIGKILL),
    then the test's own ``preexec_fn`` if it gave one."""

    def arm() -> None:
        prctl(PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0)
        if os.getppid() != parent_pid:  # the test process died before the signal was armed
            os._exit(1)
        if then is not None:
            then()

    return arm


def _popen_init_ending_with_the_run(prctl: Callable[..., int]) -> Callable[..., None]:
    """``Popen.__init__`` that arms every child started from the main thread (where tests and fixtures run, xdist's
    workers too) to get SIGTERM when this process ends: the kernel stops nodes a killed run never stopped. Not from
    another thread: the kernel takes the end of the thread that started a child for its parent's, and a helper
    thread ending would stop its child at once."""

    def init(self: subprocess.Popen[Any], *args: Any, **kwargs: Any) -> None:
        if threading.current_thread() is threading.main_thread() and len(args) < 7:  # preexec_fn not positional
            kwargs["preexec_fn"] = _arm_child(prctl, os.getpid(), kwargs.get("preexec_fn"))
        _POPEN_INIT(self, *args, **kwargs)

    return init


def _spawnv_passfds_ending_with_the_run(prctl: Callable[..., int]) -> Callable[..., int]:
    """``multiprocessing.util.spawnv_passfds`` that arms its child as :func:`_popen_init_ending_with_the_run` does a
    Popen's (main thread only). multiprocessing's ``spawn`` children (a ``Process``, a ``ProcessPoolExecutor``
    worker: physics' plan workers) and ``forkserver``'s server start through it, not through Popen: they outlived
    a killed run. It calls ``_posixsubprocess.fork_exec`` with no ``preexec_fn``: for that one call, the arming
    one is put in its place. (A ``fork`` child, or one the forkserver forks, is not armed; the resource tracker,
    started this way too, ignores SIGTERM and cleans up once the run's end closes its pipe, as before.)"""

    def spawnv_passfds(path: Any, args: Any, passfds: Sequence[int]) -> int:  # path: str here, bytes in typeshed
        if threading.current_thread() is not threading.main_thread():
            return _SPAWNV_PASSFDS(path, args, passfds)
        import _posixsubprocess  # POSIX only, as in multiprocessing.util

        fork_exec = _posixsubprocess.fork_exec
        caller = threading.get_ident()
        arm = _arm_child(prctl, os.getpid(), None)

        def fork_exec_armed(*fork_args: Any) -> int:
            if threading.get_ident() == caller and len(fork_args) > _FORK_EXEC_PREEXEC_FN \
                    and fork_args[_FORK_EXEC_PREEXEC_FN] is None:
                fork_args = (*fork_args[:_FORK_EXEC_PREEXEC_FN], arm, *fork_args[_FORK_EXEC_PREEXEC_FN + 1:])
            result: int = fork_exec(*fork_args)
            return result

        _posixsubprocess.fork_exec = fork_exec_armed  # looked up at each call by spawnv_passfds (not by Popen)
        try:
            return _SPAWNV_PASSFDS(path, args, passfds)
        finally:
            _posixsubprocess.fork_exec = fork_exec

    return spawnv_passfds


def _raise_interrupt(signum: int, frame: FrameType | None) -> None:
    """SIGTERM (a CI timeout, `timeout`, a user's kill): stop the run as Ctrl-C does, so fixtures' finalizers and
    tests' ``finally`` blocks stop what they started. A second SIGTERM ends the process at once."""
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    raise KeyboardInterrupt(f"signal {signal.Signals(signum).name}")


def _catch_sigterm() -> None:
    """Install :func:`_raise_interrupt` for SIGTERM where it is the default (never over a handler someone else set)."""
    if threading.current_thread() is threading.main_thread():
        with contextlib.suppress(ValueError, OSError):
            if signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:
                signal.signal(signal.SIGTERM, _raise_interrupt)


@pytest.fixture
def strike_core() -> Iterator[Any]:
    """Physics' core in its strike scene (a stick striking a pad; quick to build), closed after the test."""
    from services.physics.core import PhysicsCore

    core = PhysicsCore(scene="strike")
    try:
        yield core
    finally:
        core.close()


TINY_SCORE = Path(__file__).parent / "graphics" / "tiny_score.txt"
"""Four strokes (snare, hi-hat and kick; about 4 s of rig time rendered)."""


@pytest.fixture(scope="session")
def tiny_gltf_render(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The folder of ``batteur render tests/graphics/tiny_score.txt --gltf --bvh-sync wav`` (wav: the default): the
    one render the glTF, glTF flash, output length and BVH sync tests read (each module rendered it again, about
    3 s of CPU each). Read only: a test that changes a render's files copies the folder first."""
    from batteur import render

    out = tmp_path_factory.mktemp("tiny-gltf") / "out"
    assert render.main([str(TINY_SCORE), "-o", str(out), "--quiet", "--gltf", "--bvh-sync", "wav"]) == 0
    return out


def pytest_runtest_setup(item: pytest.Item) -> None:
    """Again before each test: a node run in the test process (asyncio's ``remove_signal_handler``) leaves SIGTERM
    at its default when it stops."""
    _catch_sigterm()


def pytest_configure(config: pytest.Config) -> None:
    """Point XDG_CONFIG_HOME at a folder of this run's own, inherited by every node a test starts: an interaction
    node without ``--config`` saves its routes in ``$XDG_CONFIG_HOME/batteur/interaction.yaml``, which was the
    user's own file (a route a test added there reached every later default rig on the machine).

    Make the programs tests start end with the run: SIGTERM interrupts it as Ctrl-C does (finalizers run), and on
    Linux every child started from the main thread, by subprocess or by multiprocessing's ``spawn`` (and the
    ``forkserver``'s server), gets SIGTERM from the kernel when this process ends, however it ends
    (PR_SET_PDEATHSIG)."""
    global _CONFIG_HOME
    _CONFIG_HOME = tempfile.mkdtemp(prefix="batteur-tests-config-")
    os.environ["XDG_CONFIG_HOME"] = _CONFIG_HOME
    _catch_sigterm()
    prctl = _prctl()
    if prctl is not None:
        subprocess.Popen.__init__ = _popen_init_ending_with_the_run(prctl)  # type: ignore[method-assign]
        if sys.version_info[:2] in FORK_EXEC_KNOWN:  # another CPython may have moved preexec_fn: leave it be
            multiprocessing.util.spawnv_passfds = _spawnv_passfds_ending_with_the_run(prctl)


def pytest_unconfigure(config: pytest.Config) -> None:
    subprocess.Popen.__init__ = _POPEN_INIT  # type: ignore[method-assign]
    multiprocessing.util.spawnv_passfds = _SPAWNV_PASSFDS
    if signal.getsignal(signal.SIGTERM) is _raise_interrupt:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
    if _CONFIG_HOME is not None:
        shutil.rmtree(_CONFIG_HOME, ignore_errors=True)
