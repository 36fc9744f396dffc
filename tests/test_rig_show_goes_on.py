"""``batteur rig`` on stage: the view's crash, once it was up, does not take the audio down, and the rig says when it
is ready (graphics failing at start-up stops the rig: tests/test_rig_review_fixes.py).

A live-set walkthrough (7 Dec) SIGKILLed graphics mid-set: the rig stopped physics, interaction and sound with it
("graphics was killed by SIGKILL; stopping the rig"), and the set's audio with them. And a performer driving the rig
over OSC, without ``--score``, was never told when it was up (physics took 9 s, 28 s under load): they polled Health
themselves. Stand-in services (tests/test_rig_ready.py's) answer the rig's Hellos, and any datagram, with their
Health.
"""

from __future__ import annotations

import asyncio
import io
import os
import signal
import socket
import time
from collections.abc import Callable

import pytest

from batteur import rig
from common.messages import Health, decode
from tests.ports import free_ports
from tests.test_rig_ready import StandIn

WAIT_S = 120.0
"""Generous: a loaded machine starts the stand-ins slowly."""


def answers(port: int) -> bool:
    """Whether the stand-in on ``port`` answers a datagram with its Health (within 10 s)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.settimeout(10.0)
        sock.sendto(b"hello?", ("127.0.0.1", port))
        try:
            data, _ = sock.recvfrom(65535)
        except TimeoutError:
            return False
    return any(isinstance(m, Health) for m in decode(data).messages)


async def until(condition: Callable[[], bool], what: Callable[[], str]) -> None:
    deadline = time.monotonic() + WAIT_S
    while not condition():
        assert time.monotonic() < deadline, what()
        await asyncio.sleep(0.05)


def rig_of(*roles: str, ready: bool = True) -> tuple[rig.Rig, dict[str, int], io.StringIO, io.StringIO]:
    """A rig of stand-ins of ``roles`` that waits for them to be up (``ready``: without a score); it, their ports,
    its output and its errors."""
    ports = dict(zip(roles, free_ports(len(roles)), strict=True))
    plans: list[rig.ServicePlan] = [StandIn(role, port, 0.0) for role, port in ports.items()]
    out, err = io.StringIO(), io.StringIO()
    wait = rig.ReadyWait(WAIT_S, "127.0.0.1", time.time(), None) if ready else None
    return rig.Rig(plans, stop_timeout_s=20, out=out, err=err, ready=wait), ports, out, err


def test_graphics_killed_mid_show_the_others_play_on_and_the_rig_exits_1_at_the_end() -> None:
    the_rig, ports, out, err = rig_of("physics", "sound", "graphics")
    said = lambda: out.getvalue() + err.getvalue()  # noqa: E731
    alive: list[bool] = []

    async def main() -> int:
        task = asyncio.create_task(the_rig.run(None))
        await until(lambda: "services up" in out.getvalue() or task.done(), said)
        the_rig.procs["graphics"].kill()  # the walkthrough's SIGKILL
        await until(lambda: "graphics was killed" in err.getvalue() or task.done(), said)
        # the others are still there, and still answer
        alive.extend(answers(ports[role]) for role in ("physics", "sound"))
        assert not task.done(), said()
        assert all(the_rig.procs[role].returncode is None for role in ("physics", "sound")), said()
        os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C still stops everything
        return await asyncio.wait_for(task, WAIT_S)

    code = asyncio.run(main())
    assert alive == [True, True], said()
    assert "batteur rig: graphics was killed by SIGKILL; physics, sound play on without it (Ctrl-C stops the rig; " \
           "it will exit 1: graphics failed)\n" in err.getvalue(), said()
    assert "stopping the rig" not in err.getvalue(), said()
    assert code == 1, said()  # a service failed, said by the exit status
    assert err.getvalue().endswith("batteur rig: graphics was killed by SIGKILL during the run\n"), said()
    assert all(proc.returncode is not None for proc in the_rig.procs.values())


@pytest.mark.parametrize("role", ["physics", "sound"])
def test_physics_or_sound_exiting_still_stops_the_rig(role: str) -> None:
    """Not the view: the drummer and the clock master, or the take and what is heard."""
    the_rig, _, out, err = rig_of("physics", "sound", "graphics")

    async def main() -> int:
        task = asyncio.create_task(the_rig.run(None))
        await until(lambda: "services up" in out.getvalue() or task.done(), lambda: out.getvalue() + err.getvalue())
        the_rig.procs[role].kill()
        return await asyncio.wait_for(task, WAIT_S)

    assert asyncio.run(main()) == 1
    assert f"batteur rig: {role} was killed by SIGKILL; stopping the rig\n" in err.getvalue()


def test_a_rig_of_graphics_alone_stops_when_it_exits() -> None:
    the_rig, _, out, err = rig_of("graphics", ready=False)

    async def main() -> int:
        task = asyncio.create_task(the_rig.run(None))
        await until(lambda: "graphics" in the_rig.procs or task.done(), lambda: out.getvalue() + err.getvalue())
        the_rig.procs["graphics"].kill()
        return await asyncio.wait_for(task, WAIT_S)

    assert asyncio.run(main()) == 1
    assert "batteur rig: graphics was killed by SIGKILL; stopping the rig\n" in err.getvalue()


# ---------------------------------------------------------------------------- ready, without --score


def test_without_a_score_the_rig_says_when_it_is_ready_and_where_to_send_notes() -> None:
    the_rig, ports, out, err = rig_of("physics", "sound")

    async def main() -> int:
        task = asyncio.create_task(the_rig.run(None))
        await until(lambda: "services up" in out.getvalue() or task.done(), lambda: out.getvalue() + err.getvalue())
        the_rig.stopping.set()
        return await task

    assert asyncio.run(main()) == 0, out.getvalue() + err.getvalue()
    line = next(line for line in out.getvalue().splitlines() if "services up" in line)
    assert line.startswith("batteur rig: services up ") and line.endswith(
        f": ready; send /batteur/score/load NAME or /batteur/score/note to physics at 127.0.0.1:{ports['physics']} "
        "(docs/live-control.md)"), line


def test_without_a_score_a_service_not_up_is_warned_of_and_the_rig_runs_on() -> None:
    physics = free_ports(1)[0]
    plans: list[rig.ServicePlan] = [StandIn("physics", physics, 0.0, "import time; time.sleep(120)")]
    out, err = io.StringIO(), io.StringIO()
    the_rig = rig.Rig(plans, stop_timeout_s=20, out=out, err=err,
                      ready=rig.ReadyWait(1.0, "127.0.0.1", time.time(), None))

    async def main() -> int:
        task = asyncio.create_task(the_rig.run(None))
        await until(lambda: "not up" in err.getvalue() or task.done(), lambda: out.getvalue() + err.getvalue())
        assert not task.done()  # no score waits on it: the rig runs on
        the_rig.stopping.set()
        return await task

    assert asyncio.run(main()) == 0, out.getvalue() + err.getvalue()
    assert err.getvalue().startswith("batteur rig: warning: physics not up within --ready-timeout 1 s of launch "
                                     "(no answer to a Hello); the rig runs on"), err.getvalue()


def test_the_rig_waits_for_its_services_without_a_score_too(monkeypatch: pytest.MonkeyPatch) -> None:
    """``main`` gives the rig a :class:`rig.ReadyWait` with or without ``--score`` (until 7 Dec only with it)."""
    given: list[rig.ReadyWait | None] = []

    async def fake_run(plans: list[rig.ServicePlan], opts: object, ready: rig.ReadyWait | None = None) -> int:
        given.append(ready)
        return 0

    monkeypatch.setattr(rig, "run_rig", fake_run)
    base = free_ports(4)[0]
    assert rig.main(["--services", "physics,sound", "--no-discovery", "--base-port", str(base),
                     "--ready-timeout", "30"]) == 0
    assert len(given) == 1 and given[0] is not None
    assert (given[0].timeout_s, given[0].play_at_s) == (30.0, None)
