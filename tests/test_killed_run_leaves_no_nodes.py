"""A test run stopped by SIGTERM (a CI timeout, `timeout`, a user's kill) or SIGKILL takes down the node processes
and the multiprocessing ``spawn`` children (a Process, a ProcessPoolExecutor's worker, as physics' plan workers and
render's segment workers are) its tests started (tests/conftest.py): one run left nine graphics nodes loading the
machine. Each test runs a pytest of its own (with tests/conftest.py as its plugin) whose test starts nodes and
spawn children and sleeps, kills that pytest, and looks for them."""

from __future__ import annotations

import multiprocessing
import os
import signal
import subprocess
import sys
import textwrap
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.conftest import FORK_EXEC_KNOWN
from tests.test_runtime import NODE_SCRIPT
from tests.waiting import until

pytestmark = [pytest.mark.timeout(120),
              pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc; prctl is Linux's")]

ROOT = Path(__file__).resolve().parents[1]

INNER_TEST = textwrap.dedent(
    """
    import multiprocessing
    import os
    import subprocess
    import sys
    import time
    from concurrent.futures import ProcessPoolExecutor
    from pathlib import Path

    import pytest

    OUT = Path(os.environ["KILLED_RUN_DIR"])


    def start_node(name):
        # a node of the runtime, discovery and OSCQuery off, as the tests start them
        proc = subprocess.Popen([sys.executable, str(OUT / "node.py"), "--no-discovery", "--no-oscquery",
                                 "--clock-master", "self"], stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL)
        (OUT / f"{name}.pid").write_text(str(proc.pid))
        return proc


    def start_time(pid):
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[19]


    def start_spawn_children():
        # started as multiprocessing starts them (not by Popen): a daemon Process (the run's exit stops it on
        # SIGTERM) and a pool's idle worker, which waits for work on a pipe it holds both ends of
        ctx = multiprocessing.get_context("spawn")
        process = ctx.Process(target=time.sleep, args=(600,), daemon=True)
        process.start()
        pool = ProcessPoolExecutor(1, mp_context=ctx)
        worker = pool.submit(os.getpid).result(timeout=60)
        for name, pid in (("spawn-process", process.pid), ("pool-worker", worker)):
            (OUT / f"{name}.mppid").write_text(f"{pid} {start_time(pid)}")
        return process, pool


    def test_a_node_run_in_the_test_process_resets_sigterm():
        # as run_node's loop does when it stops: asyncio puts SIGTERM back to its default, not to what it was
        import asyncio
        import signal

        async def main():
            asyncio.get_running_loop().add_signal_handler(signal.SIGTERM, lambda: None)
            asyncio.get_running_loop().remove_signal_handler(signal.SIGTERM)

        asyncio.run(main())
        assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL


    @pytest.fixture
    def node():
        proc = start_node("fixture-node")
        yield proc
        proc.terminate()
        proc.wait(10)
        (OUT / "finalized").write_text("yes")


    def test_starts_nodes_then_sleeps(node):
        start_node("bare-node")  # never stopped by the test: only the kernel stops it
        children = start_spawn_children()  # noqa: F841 (kept alive while the test sleeps)
        (OUT / "sleeping").write_text("yes")
        time.sleep(600)
    """
)


def _alive(pid: int, script: Path) -> bool:
    """True while ``pid`` is the node running ``script`` (not a zombie; never another process that got its pid)."""
    try:
        cmdline = Path(f"/proc/{pid}/cmdline").read_bytes()
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return False
    return str(script).encode() in cmdline and state not in ("Z", "X")


def _spawn_child_alive(pid: int, start: str) -> bool:
    """True while ``pid`` is the multiprocessing child that started at ``start`` (/proc's clock ticks since boot),
    not a zombie."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except (OSError, IndexError):
        return False
    return fields[19] == start and fields[0] not in ("Z", "X")


def _spawn_children(out: Path) -> dict[str, tuple[int, str]]:
    """The inner test's multiprocessing children: name -> (pid, start time)."""
    children: dict[str, tuple[int, str]] = {}
    for f in out.glob("*.mppid"):
        pid, start = f.read_text().split()
        children[f.stem] = (int(pid), start)
    return children


def _left_running(out: Path, nodes: dict[str, int], children: dict[str, tuple[int, str]]) -> list[str]:
    return [name for name, pid in nodes.items() if _alive(pid, out / "node.py")] + \
        [name for name, (pid, start) in children.items() if _spawn_child_alive(pid, start)]


@pytest.fixture
def killed_run(tmp_path: Path) -> Iterator[tuple[subprocess.Popen[bytes], Path]]:
    """A pytest running :data:`INNER_TEST` with tests/conftest.py, once its test sleeps; its folder. Whatever of it
    is left at the end (this test failed) is stopped: the pytest, and the nodes it started, by their pids."""
    out = tmp_path / "run"
    out.mkdir()
    (out / "node.py").write_text(NODE_SCRIPT)
    (out / "test_inner.py").write_text(INNER_TEST)
    env = {k: v for k, v in os.environ.items() if not k.startswith(("BATTEUR_", "PYTEST_"))}
    env.update(PYTHONPATH=str(ROOT) + os.pathsep + env.get("PYTHONPATH", ""), KILLED_RUN_DIR=str(out))
    run = subprocess.Popen([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "tests.conftest",
                            "-p", "no:randomly", "--rootdir", str(out), str(out / "test_inner.py")],
                           cwd=out, env=env, stdin=subprocess.DEVNULL, stdout=(out / "pytest.log").open("wb"),
                           stderr=subprocess.STDOUT)
    try:
        assert until(lambda: (out / "sleeping").exists() or run.poll() is not None, timeout_s=60), "never slept"
        assert run.poll() is None, (out / "pytest.log").read_text()
        yield run, out
    finally:
        if run.poll() is None:
            run.kill()
        run.wait()
        for pid_file in out.glob("*.pid"):
            pid = int(pid_file.read_text())
            if _alive(pid, out / "node.py"):
                os.kill(pid, signal.SIGKILL)
        for pid, start in _spawn_children(out).values():
            if _spawn_child_alive(pid, start):
                os.kill(pid, signal.SIGKILL)


def _nodes(out: Path) -> dict[str, int]:
    return {f.stem: int(f.read_text()) for f in out.glob("*.pid")}


def test_a_run_stopped_by_sigterm_runs_its_finalizers_and_leaves_no_node(
        killed_run: tuple[subprocess.Popen[bytes], Path]) -> None:
    run, out = killed_run
    nodes, children = _nodes(out), _spawn_children(out)
    assert set(nodes) == {"fixture-node", "bare-node"}
    assert set(children) == {"spawn-process", "pool-worker"}
    assert len(_left_running(out, nodes, children)) == 4
    run.send_signal(signal.SIGTERM)
    assert run.wait(timeout=60) != 0
    log = (out / "pytest.log").read_text()
    assert (out / "finalized").exists(), log  # the fixture stopped its node, as on Ctrl-C
    assert "KeyboardInterrupt" in log and "SIGTERM" in log, log
    assert until(lambda: not _left_running(out, nodes, children), timeout_s=30), \
        f"left running: {_left_running(out, nodes, children)}"


def test_a_run_killed_by_sigkill_leaves_no_node(killed_run: tuple[subprocess.Popen[bytes], Path]) -> None:
    run, out = killed_run
    nodes, children = _nodes(out), _spawn_children(out)
    assert set(children) == {"spawn-process", "pool-worker"}
    assert len(_left_running(out, nodes, children)) == 4
    run.kill()  # no handler, no finalizer: the kernel's signal to the children alone
    run.wait()
    assert until(lambda: not _left_running(out, nodes, children), timeout_s=30), \
        f"left running: {_left_running(out, nodes, children)}"
    assert not (out / "finalized").exists()


PDEATHSIG_OF_CHILD = ("import ctypes; v = ctypes.c_int(-1); "
                      "ctypes.CDLL(None).prctl(2, ctypes.byref(v), 0, 0, 0); print(v.value)")  # PR_GET_PDEATHSIG


def _child_pdeathsig(**kwargs: object) -> int:
    return int(subprocess.run([sys.executable, "-c", PDEATHSIG_OF_CHILD], capture_output=True, text=True,
                              check=True, **kwargs).stdout)  # type: ignore[call-overload]


def test_children_of_the_main_thread_are_armed_and_keep_their_own_preexec_fn(tmp_path: Path) -> None:
    assert _child_pdeathsig() == signal.SIGTERM
    marker = tmp_path / "ran"
    assert _child_pdeathsig(preexec_fn=lambda: os.close(os.open(marker, os.O_CREAT | os.O_WRONLY))) == \
        signal.SIGTERM
    assert marker.exists()


@pytest.mark.skipif(sys.version_info[:2] not in FORK_EXEC_KNOWN, reason="fork_exec's preexec_fn not where known")
def test_spawn_children_of_the_main_thread_are_armed(tmp_path: Path) -> None:
    """multiprocessing starts them with ``_posixsubprocess.fork_exec``, not Popen."""
    got = tmp_path / "pdeathsig"
    code = (f"import ctypes, pathlib; v = ctypes.c_int(-1); ctypes.CDLL(None).prctl(2, ctypes.byref(v), 0, 0, 0); "
            f"pathlib.Path({str(got)!r}).write_text(str(v.value))")  # PR_GET_PDEATHSIG
    process = multiprocessing.get_context("spawn").Process(target=exec, args=(code,))
    process.start()
    process.join(60)
    assert process.exitcode == 0
    assert int(got.read_text()) == signal.SIGTERM


def test_children_of_another_thread_are_not_armed() -> None:
    """The kernel signals a child when the *thread* that started it ends: a helper thread's child would stop with
    that thread."""
    got: list[int] = []
    thread = threading.Thread(target=lambda: got.append(_child_pdeathsig()))
    thread.start()
    thread.join()
    assert got == [0]
