"""``batteur rig`` as a user runs it: bad options refused before any service starts, services stopped whatever
happens to the rig (Ctrl-C while they load, a closed output, a closed terminal), the recording kept only whole.

Stand-in services (a few lines of Python) play the services where the rig's own behaviour is tested, so no test
here builds a drummer.
"""

from __future__ import annotations

import asyncio
import contextlib
import io
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from batteur import rig
from tests.ports import free_ports


class NoRig:
    """Stands in for :class:`rig.Rig`: a refused option must not get this far."""

    def __init__(self, plans: list[rig.ServicePlan], *args: object, **kwargs: object) -> None:
        raise AssertionError(f"services would start: {[p.role for p in plans]}")


class Plan(rig.ServicePlan):
    """A stand-in service: ``python -c CODE ARGS``."""

    def __init__(self, role: str, code: str, *args: str) -> None:
        super().__init__(role, 0, list(args))
        self.code = code

    def argv(self) -> list[str]:
        return [sys.executable, "-c", self.code, *self.args]


class GoneStream(io.TextIOBase):
    """An output whose reader has gone (``batteur rig | head`` after head exits)."""

    def write(self, text: str) -> int:
        raise BrokenPipeError(32, "Broken pipe")


LOADING = ("import sys, time\ntry:\n    time.sleep(60)\n"
           "except KeyboardInterrupt:\n    print('interrupted'); sys.exit(130)")
"""A service still loading its modules: no signal handler yet, and ``batteur``'s Ctrl-C handling (exit code 130)."""
WRITE_PID = "import os, sys, time; open(sys.argv[1], 'w').write(str(os.getpid())); time.sleep(60)"


def refused(argv: list[str], capsys: pytest.CaptureFixture[str], status: int = 2) -> str:
    """Run the rig with ``argv``; assert exit code ``status`` (2: a bad command line, 1: a file or port it cannot
    use) and return what it printed to stderr."""
    try:
        code = rig.main(argv)
    except SystemExit as exc:  # argparse's usage error
        code = exc.code  # type: ignore[assignment]
    assert code == status
    return capsys.readouterr().err


def running(pid: int) -> bool:
    """Whether ``pid`` is a live process (a zombie left to a non-reaping init counts as gone)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError):
        return False
    return state != "Z"


def wait_for_file(path: Path, timeout_s: float = 30.0) -> str:
    deadline = time.monotonic() + timeout_s
    while not (path.exists() and path.read_text()):
        assert time.monotonic() < deadline, f"{path} not written in {timeout_s} s"
        time.sleep(0.05)
    return path.read_text()


@pytest.fixture
def no_rig(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    monkeypatch.setattr(rig, "Rig", NoRig)
    yield


@pytest.mark.parametrize("argv", [
    ["--duration", "nan"], ["--duration", "-1"], ["--stop-timeout", "0"], ["--start-delay", "-3"],
    ["--score", "demo", "--play-at", "nan"], ["--score", "demo", "--play-at", "inf"],
    ["--base-port", "0"], ["--base-port", "65534"], ["--services", "interaction,interaction"],
    ["--strike-period", "-1"], ["--strike-period", "1", "--strike-velocity", "inf"], ["--log-level", "loud"],
    ["--record", "rec", "--services", "physics,interaction"], ["--http-port", "-1"], ["--http-port", "65536"],
])
def test_bad_values_are_refused_before_any_service_starts(argv: list[str], no_rig: None, tmp_path: Path,
                                                          monkeypatch: pytest.MonkeyPatch,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    err = refused(["--no-discovery", *argv], capsys)
    assert argv[0] in err and "Traceback" not in err
    assert not (tmp_path / "rec").exists()


def test_a_port_in_use_is_refused_before_any_service_starts(no_rig: None,
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as held:
        held.bind(("127.0.0.1", 0))
        port = held.getsockname()[1]
        if port < 3:
            pytest.skip("no room below the held port")
        err = refused(["--no-discovery", "--services", "interaction,sound", "--base-port", str(port - 2)], capsys, 1)
    assert f"UDP port {port} (sound) on 127.0.0.1 is in use" in err


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs /proc")
def test_a_recording_folder_that_cannot_be_made_is_a_one_line_error(no_rig: None,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    # /proc passes the writability check as root, and still no folder can be made in it
    err = refused(["--no-discovery", "--services", "sound", "--base-port", str(free_ports(4)[0]),
                   "--record", "/proc/batteur-rig-test/out"], capsys, 1)
    assert err.startswith("batteur rig: error: --record /proc/batteur-rig-test/out: cannot create a folder in /proc")


def test_a_folder_named_demo_does_not_hide_the_demo_groove(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    started: list[rig.ServicePlan] = []

    class Recorder:
        def __init__(self, plans: list[rig.ServicePlan], *args: object, **kwargs: object) -> None:
            started.extend(plans)

        async def run(self, duration_s: float | None) -> int:
            return 0

    monkeypatch.setattr(rig, "Rig", Recorder)
    monkeypatch.chdir(tmp_path)
    (tmp_path / "demo").mkdir()
    assert rig.main(["--no-discovery", "--services", "physics", "--base-port", str(free_ports(4)[0]),
                     "--score", "demo"]) == 0
    args = started[0].args
    assert Path(args[args.index("--score") + 1]).name == "demo-groove.txt"


def test_a_service_still_loading_when_the_rig_stops_stops_cleanly(capsys: pytest.CaptureFixture[str]) -> None:
    # a Ctrl-C (or --duration) while the services load: SIGINT gave each "interrupted" (or, in the interpreter's
    # start, a "Fatal Python error" traceback) and the rig exit code 1
    plans: list[rig.ServicePlan] = [Plan("physics", LOADING), Plan("sound", LOADING)]
    the_rig = rig.Rig(plans, stop_timeout_s=20)
    assert asyncio.run(the_rig.run(0.2)) == 0
    assert all(proc.returncode is not None for proc in the_rig.procs.values())
    captured = capsys.readouterr()
    assert "Traceback" not in captured.out + captured.err  # a service's stderr is the rig's stderr


def test_the_rig_exits_with_the_code_of_the_service_that_failed() -> None:
    plans: list[rig.ServicePlan] = [Plan("physics", "import sys; sys.exit(2)"), Plan("sound", LOADING)]
    the_rig = rig.Rig(plans, stop_timeout_s=20)
    assert asyncio.run(the_rig.run(60)) == 2  # 2: the service refused its options
    assert not the_rig.stopped_cleanly("physics")


def test_the_rig_stops_its_services_when_its_output_is_gone(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sys, "stdout", GoneStream())
    monkeypatch.setattr(sys, "stderr", GoneStream())
    pid_file = tmp_path / "pid"
    the_rig = rig.Rig([Plan("sound", WRITE_PID, str(pid_file))], stop_timeout_s=20)

    async def run_then_stop() -> int:
        task = asyncio.create_task(the_rig.run(None))
        while not (pid_file.exists() and pid_file.read_text()):
            assert not task.done(), "the rig stopped before its service started"
            await asyncio.sleep(0.05)
        the_rig.stopping.set()
        return await task

    try:
        asyncio.run(run_then_stop())
    finally:
        for proc in the_rig.procs.values():
            if proc.returncode is None:
                os.kill(proc.pid, signal.SIGKILL)
    assert not running(int(pid_file.read_text()))


def test_a_service_printing_a_very_long_line_does_not_block(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # asyncio's line reader gives up on a line over its limit; the rig must keep reading, else the service
    # blocks on its next write to the full pipe and never stops
    pid_file = tmp_path / "pid"
    chatty = ("import sys; print('x' * (3 << 20)); [print('y' * 100) for _ in range(20000)]; sys.stdout.flush(); "
              + WRITE_PID)
    monkeypatch.setattr(sys, "stdout", io.StringIO())
    the_rig = rig.Rig([Plan("sound", chatty, str(pid_file))], stop_timeout_s=20)

    async def run_then_stop() -> None:
        task = asyncio.create_task(the_rig.run(None))
        try:
            await asyncio.to_thread(wait_for_file, pid_file)
        finally:
            the_rig.stopping.set()
            await task

    asyncio.run(run_then_stop())


@contextlib.contextmanager
def rig_with_one_service(tmp_path: Path) -> Iterator[tuple[subprocess.Popen[bytes], int]]:
    """A rig process running one stand-in service: (the rig, the service's pid); both are gone afterwards."""
    pid_file = tmp_path / "pid"
    script = (
        "import asyncio, sys\n"
        "from batteur.rig import Rig\n"
        "from tests.test_rig_inputs import Plan, WRITE_PID\n"
        f"sys.exit(asyncio.run(Rig([Plan('sound', WRITE_PID, {str(pid_file)!r})], 20).run(None)))\n"
    )
    the_rig = subprocess.Popen([sys.executable, "-c", script], cwd=Path(__file__).resolve().parents[1],
                               stdout=subprocess.DEVNULL)
    pid = 0
    try:
        pid = int(wait_for_file(pid_file))
        yield the_rig, pid
    finally:
        the_rig.kill()
        if pid and running(pid):
            os.kill(pid, signal.SIGKILL)


def test_closing_the_terminal_stops_the_services(tmp_path: Path) -> None:
    # SIGHUP (the terminal closed) killed the rig and left its services, in their own sessions, running
    with rig_with_one_service(tmp_path) as (the_rig, pid):
        the_rig.send_signal(signal.SIGHUP)
        assert the_rig.wait(timeout=30) == 0
        assert not running(pid)


@pytest.mark.skipif(rig.stop_with_the_rig() is None, reason="needs Linux's prctl")
def test_a_rig_killed_outright_leaves_no_service_running(tmp_path: Path) -> None:
    # SIGKILL gives the rig no chance to stop its services: they, in their own sessions, ran on as orphans
    with rig_with_one_service(tmp_path) as (the_rig, pid):
        the_rig.kill()
        the_rig.wait(timeout=30)
        deadline = time.monotonic() + 30
        while running(pid) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not running(pid)


def test_a_view_port_in_use_is_refused_before_any_service_starts(no_rig: None,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    # a second rig on one machine: its graphics could not serve the view on 8080, and stopped the rig once started
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as held:
        held.bind(("127.0.0.1", 0))
        held.listen()
        port = held.getsockname()[1]
        err = refused(["--no-discovery", "--services", "graphics", "--base-port", str(free_ports(4)[0]),
                       "--http-port", str(port)], capsys, 1)
    assert f"TCP port {port} (graphics view) on 127.0.0.1 is in use" in err and "--http-port" in err


def test_graphics_serves_the_view_on_the_rigs_http_port() -> None:
    opts = rig.build_parser().parse_args(["--http-port", "8181"])
    args = rig.role_args("graphics", opts)
    assert args[args.index("--http-port") + 1] == "8181"
    assert "--http-port" not in rig.role_args("sound", opts)
