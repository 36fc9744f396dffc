"""Closing a live sound core abandons a parameter change in flight: nothing waits for it, its child interpreter
is killed, and its result is dropped."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import threading
import time
from collections.abc import Callable
from pathlib import Path

import pytest
from sound_helpers import one_drum_kit

from common.messages.sound import SoundModes
from services.sound import core as core_module
from services.sound import membrane
from services.sound.core import SoundCore, SoundSettings

REPO = Path(__file__).resolve().parents[2]


def _live_core() -> SoundCore:
    return SoundCore(SoundSettings(latency=0.01, use_pyo=False, record=False, background_rebuilds=True),
                     one_drum_kit())


def _wait(cond: Callable[[], object], what: str, timeout_s: float = 60.0) -> None:
    """Poll ``cond()`` until true (a generous deadline against a hang, not a timing assertion)."""
    deadline = time.monotonic() + timeout_s
    while not cond():
        assert time.monotonic() < deadline, what
        time.sleep(0.01)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


def test_close_kills_the_child_interpreter_of_a_rebuild_in_flight(monkeypatch: pytest.MonkeyPatch,
                                                                   tmp_path: Path) -> None:
    pid_file = tmp_path / "child.pid"
    # the child that computes a large Bessel-zero table, made to hang (it would compute for seconds)
    monkeypatch.setattr(membrane, "_CHILD", f"import os, time; open({str(pid_file)!r}, 'w').write(str(os.getpid()));"
                        " time.sleep(600)")
    monkeypatch.setattr(membrane, "_TABLES", [])  # as in a fresh process: the change needs the child
    core = _live_core()
    drum = core.instruments.instruments["drum"]
    try:
        core.handle(SoundModes(instrument="drum", value=20000), core.now, "panel")
        _wait(lambda: pid_file.exists() and pid_file.read_text(), "the rebuild never started its child")
        pid = int(pid_file.read_text())
        assert _alive(pid)
    finally:
        core.close()
    # was: the child computed on (up to its 600 s timeout) after the node had stopped
    _wait(lambda: not _alive(pid), "the child interpreter outlived the core")
    core.step(core.now + 0.1)
    assert drum.p.n_modes == 160 and not core.rebuilding  # the change was dropped, not half applied


def test_a_change_finishing_after_close_is_dropped(monkeypatch: pytest.MonkeyPatch) -> None:
    started, release, finished = threading.Event(), threading.Event(), threading.Event()
    real = core_module._apply_changes

    def slow(twin, changes):  # type: ignore[no-untyped-def]
        started.set()
        release.wait(120)
        result = real(twin, changes)
        finished.set()
        return result

    monkeypatch.setattr(core_module, "_apply_changes", slow)
    core = _live_core()
    drum = core.instruments.instruments["drum"]
    core.handle(SoundModes(instrument="drum", value=300), core.now, "panel")
    core.handle(SoundModes(instrument="drum", value=400), core.now, "panel")  # queued behind it
    _wait(started.is_set, "the rebuild never started")
    core.close()  # returns while the rebuild is still held
    assert not release.is_set()
    release.set()
    _wait(finished.is_set, "the rebuild never finished")
    core.step(core.now + 0.05)
    # was: the next step swapped the finished change in, after close
    assert drum.p.n_modes == 160 and drum.bank.size == 195
    assert not core.rebuilding


def test_a_process_exits_without_waiting_for_a_rebuild_in_flight() -> None:
    script = textwrap.dedent("""
        import sys, threading
        sys.path[:0] = [{repo!r}, {tests!r}]
        from sound_helpers import one_drum_kit
        from common.messages.sound import SoundModes
        from services.sound import core as core_module
        from services.sound.core import SoundCore, SoundSettings

        started = threading.Event()

        def never_ends(twin, changes):  # a rebuild that would hold the process for ever
            started.set()
            threading.Event().wait()

        core_module._apply_changes = never_ends
        core = SoundCore(SoundSettings(use_pyo=False, record=False, background_rebuilds=True), one_drum_kit())
        core.handle(SoundModes(instrument="drum", value=300), core.now, "panel")
        assert started.wait(60)
        core.close()
        print("closed", flush=True)
    """).format(repo=str(REPO), tests=str(REPO / "tests" / "sound"))
    # was: the interpreter joined the worker thread at exit, i.e. never exited (the timeout is that hang's guard)
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120,
                          cwd=REPO)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "closed"
