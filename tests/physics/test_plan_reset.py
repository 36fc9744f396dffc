"""A reset (or a divergence) while a background plan is computed: the next plan does not wait for the dropped one,
and the planning processes never leak (none left running or unreaped after a reset, none after the core closes,
none after the node is killed).

The "long plan" is held in the worker until the test releases it (a file appears, 60 s at most): a plan asked for
after the reset must be ready well within that, so it did not wait behind the dropped one. No wall-clock bound is
tight: the short plan takes milliseconds, the bound is 20 s.
"""

from __future__ import annotations

import functools
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from common.gesture.plan import GesturePlan
from common.messages.physics import PhysicsReset
from common.messages.score import ScoreLoad, ScoreTransport
from services.physics.node import LivePhysicsCore
from tests.waiting import until

SCORES = Path(__file__).parents[1] / "render"
SCORE = "short_groove.txt"  # two bars: a plan of milliseconds
SENDER = "127.0.0.1:9"
HOLD_S = 60.0
"""The held plan waits this long at most for its release, seconds."""
READY_S = 20.0
"""A plan asked for after the reset must be ready within this, seconds (the held one is still held then)."""


def _held_plan(started: str, release: str, hold_s: float, planner: Callable[[], GesturePlan]) -> GesturePlan:
    """A plan that creates the file ``started`` then waits for the file ``release`` (``hold_s`` s at most) before
    planning; picklable, for a process."""
    Path(started).touch()
    deadline = time.monotonic() + hold_s
    while not os.path.exists(release) and time.monotonic() < deadline:
        time.sleep(0.01)
    return planner()


def _hold_next_plan(core: LivePhysicsCore, release: Path) -> None:
    """The next plan the player starts is held until ``release`` exists; the plans after it are not."""
    player = core.score_player
    original = player._planner

    def planner(*args: Any) -> Callable[[], GesturePlan]:
        player._planner = original  # type: ignore[method-assign]
        return functools.partial(_held_plan, str(release.with_name("started")), str(release), HOLD_S,
                                 original(*args))

    player._planner = planner  # type: ignore[method-assign]


def _children() -> dict[int, str]:
    """This process's child processes: pid -> state (R, S, Z ...), the resource tracker left out (multiprocessing
    starts one per interpreter, for good)."""
    me, out = os.getpid(), {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
            cmdline = (entry / "cmdline").read_bytes()
        except OSError:  # ended meanwhile
            continue
        fields = stat[stat.rindex(")") + 2:].split()
        if int(fields[1]) == me and b"resource_tracker" not in cmdline:
            out[int(entry.name)] = fields[0]
    return out


@pytest.fixture
def release(tmp_path: Path) -> Iterator[Path]:
    path = tmp_path / "release"
    yield path
    path.touch()  # a held plan (a thread's cannot be stopped) ends with the test


def _live(planner: str, pose_rate_hz: float = 0.0) -> LivePhysicsCore:
    core = LivePhysicsCore(scene="drummer", grip="german", pose_rate_hz=pose_rate_hz, mode="live",
                           planner=planner)  # type: ignore[arg-type]
    assert core.score_player.wait_loaded(120.0)  # as the node before it listens (play: refused meanwhile)
    core.score_player.library = [SCORES]
    core.handle(ScoreLoad(path=SCORE), 0.0, SENDER)
    return core


def _play_held_then_reset_then_play(core: LivePhysicsCore, release: Path) -> bool:
    """A held play, a reset once the worker computes it, a play: whether the second plan is ready within READY_S
    (then spliced)."""
    player = core.score_player
    _hold_next_plan(core, release)
    assert core.handle(ScoreTransport(action="play", time=0.0, position=0.0), 0.1, SENDER) == []
    assert until(release.with_name("started").exists, 60.0) and player.busy
    assert core.handle(PhysicsReset(time=0.1), 0.1, SENDER) == []
    assert until(lambda: not player.loading, 60.0)  # the spare, started after the first plan, may still load
    assert core.handle(ScoreTransport(action="play", time=0.0, position=0.0), 0.1, SENDER) == []
    ready = player.wait(READY_S)
    assert not release.exists()
    core.step(core.time + 0.001)
    return ready


@pytest.mark.parametrize("planner", ["process", "thread"])
def test_a_plan_asked_after_a_reset_does_not_wait_for_the_dropped_one(planner: str, release: Path) -> None:
    """A reset drops a plan being computed; the play sent after it is planned at once (by a fresh worker), not
    once the dropped plan is done: it is ready and played while the dropped one would still be computing."""
    core = _live(planner)
    player = core.score_player
    try:
        assert core.handle(ScoreTransport(action="play", time=0.0, position=0.0), 0.0, SENDER) == []
        assert player.wait(60.0)  # a first plan: the worker is up and its database loaded
        core.step(core.time + 0.001)
        assert player.plans == 1
        assert _play_held_then_reset_then_play(core, release), "the plan after the reset waited for the dropped one"
        assert player.plans == 2 and player.state == "playing" and core.rejected_total == 0
        release.touch()
        for _ in range(50):  # the dropped plan, if a thread finishes it, is never spliced
            time.sleep(0.002)
            core.step(core.time + 0.001)
        assert player.plans == 2 and core.rejected_total == 0
    finally:
        core.close()


def test_a_divergence_drops_the_plan_in_flight_and_the_next_plan_does_not_wait_for_it(release: Path) -> None:
    """A diverged simulation is reset as /batteur/physics/reset would: the plan being computed is dropped and
    stopped too (it was left computing, and every later message waited behind it). Poses on: reading the
    non-finite state poked in is what finds the divergence."""
    core = _live("process", pose_rate_hz=60.0)
    player = core.score_player
    try:
        assert core.handle(ScoreTransport(action="play", time=0.0, position=0.0), 0.0, SENDER) == []
        assert player.wait(60.0)
        core.step(core.time + 0.001)
        core.handle(PhysicsReset(time=core.time), core.time, SENDER)  # at rest: the divergence's reset restores it
        _hold_next_plan(core, release)
        assert core.handle(ScoreTransport(action="play", time=0.0, position=0.0), core.time, SENDER) == []
        assert until(release.with_name("started").exists, 60.0) and player.busy
        trunk = core.scene.body.parts[0]  # type: ignore[attr-defined]
        core.world.client.resetJointState(trunk.id, trunk.state_joints[5], float("nan"), 0.0)
        for _ in range(200):
            if core.diverged:
                break
            core.step(core.time + 0.001)
        assert core.diverged == 1 and not player.busy and player.state == "idle"
        assert until(lambda: not player.loading, 60.0)  # the spare, started after the first plan, may still load
        assert core.handle(ScoreTransport(action="play", time=0.0, position=0.0), core.time, SENDER) == []
        assert player.wait(READY_S), "the plan after the divergence waited for the dropped one"
        assert not release.exists()
        core.step(core.time + 0.001)
        assert player.plans == 2 and player.state == "playing" and core.rejected_total == 0
    finally:
        core.close()

def test_the_planning_processes_are_reaped_after_a_reset_and_end_with_the_core(release: Path) -> None:
    """The process computing a dropped plan is stopped and reaped (no zombie); the node keeps two planning
    processes (the one planning and a started spare); closing the core ends them all."""
    before = _children()
    core = _live("process")
    player = core.score_player
    try:
        assert core.handle(ScoreTransport(action="play", time=0.0, position=0.0), 0.0, SENDER) == []
        assert player.wait(60.0)
        core.step(core.time + 0.001)
        planners = set(_children()) - set(before)
        assert _play_held_then_reset_then_play(core, release)
        assert until(lambda: len(set(_children()) - set(before)) == len(planners)), _children()
        now = {pid: state for pid, state in _children().items() if pid not in before}
        assert "Z" not in now.values() and len(now) == 2 and len(set(now) & planners) == 1, (planners, now)
    finally:
        core.close()
    assert until(lambda: set(_children()) <= set(before)), (before, _children())


def test_closing_the_core_ends_a_planning_process_in_the_middle_of_a_plan(release: Path) -> None:
    """The node closes its core when it stops (Ctrl-C, SIGTERM): a process computing a plan then is terminated, not
    left to finish it (it was: the executor forgot its processes at shutdown, before they were terminated)."""
    before = _children()
    core = _live("process")
    player = core.score_player
    try:
        _hold_next_plan(core, release)
        assert core.handle(ScoreTransport(action="play", time=0.0, position=0.0), 0.0, SENDER) == []
        assert until(release.with_name("started").exists, 60.0) and player.busy
    finally:
        core.close()
    assert until(lambda: set(_children()) <= set(before)), (before, _children())
    assert not release.exists()  # ended well before the held plan would have


KILLED_NODE = """
import time
from services.physics.plan_worker import PlanWorkers
if __name__ == "__main__":
    workers = PlanWorkers("process")
    workers.submit(int).result()
    workers.idle()
    print(*[p.pid for pool in (workers._current, workers._spare) for p in pool._processes.values()], flush=True)
    time.sleep(120)
"""


def _dead(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return True
    return stat[stat.rindex(")") + 2] in "ZX"  # exited, not yet reaped by init


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG is Linux's")
def test_the_planning_processes_end_when_the_node_is_killed() -> None:
    """A node killed (SIGKILL, a crash) never closes its core: its planning processes, idle on their queue, must
    not live on without it (they did, 120 MB each, for good)."""
    node = subprocess.Popen([sys.executable, "-c", KILLED_NODE], stdout=subprocess.PIPE, text=True,
                            cwd=Path(__file__).parents[2])
    try:
        assert node.stdout is not None
        planners = [int(pid) for pid in node.stdout.readline().split()]
        assert len(planners) == 2 and not any(_dead(pid) for pid in planners)
    finally:
        node.send_signal(signal.SIGKILL)
        node.wait()
    assert until(lambda: all(_dead(pid) for pid in planners)), [(p, _dead(p)) for p in planners]
