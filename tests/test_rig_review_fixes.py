"""``batteur rig``: a service it cannot start stops the rig; a graphics exit says the code the rig will exit with.

Review of 6c221a4 (7 Dec): a service whose process could not be created (``OSError``: a missing interpreter, no
memory, no free process slot) was said ("cannot start sound: ...") but the services already started ran on, the rig
waiting for Ctrl-C with nothing more said and no "services up" line. And graphics exiting with 2 while the others
played on was said as "it will exit 1", the rig then exiting 2. The review of 66552ee: graphics refusing its options
at start-up (a typo in ``--graphics-arg``) should stop the rig, not play on; only a graphics that was up does. The
review of 95cc588: without ``--score`` a graphics still running when the rig stopped waiting for it is up too, and one
ending with 0 before it was up stops the rig with 1. Stand-in services (tests/test_rig_ready.py's) answer the rig's
Hellos with their Health.
"""

from __future__ import annotations

import asyncio
import io
import socket
import time

import pytest

from batteur import rig
from common.messages import Health, decode
from tests.ports import free_ports
from tests.test_rig_ready import StandIn
from tests.test_rig_show_goes_on import until

WAIT_S = 120.0
"""Generous: a loaded machine starts the stand-ins slowly."""


class Unstartable(rig.ServicePlan):
    """A service whose program does not exist: creating its process raises ``OSError``."""

    def argv(self) -> list[str]:
        return ["/nonexistent/batteur-review/python3"]


def answers(port: int, timeout_s: float) -> bool:
    """Whether the stand-in on ``port`` answers a datagram with its Health within ``timeout_s`` seconds."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.settimeout(timeout_s)
        sock.sendto(b"hello?", ("127.0.0.1", port))
        try:
            data, _ = sock.recvfrom(65535)
        except (TimeoutError, ConnectionRefusedError):  # not listening yet: ICMP port unreachable
            return False
    return any(isinstance(m, Health) for m in decode(data).messages)


def run(the_rig: rig.Rig, err: io.StringIO, until: str) -> int:
    """Run ``the_rig`` until its errors (``err``) say ``until`` (then stop it) or it stops by itself; its exit
    code."""

    async def main() -> int:
        task = asyncio.create_task(the_rig.run(None))
        deadline = time.monotonic() + WAIT_S
        while until not in err.getvalue() and not task.done():
            assert time.monotonic() < deadline, err.getvalue()
            await asyncio.sleep(0.05)
        if not task.done():
            the_rig.stopping.set()
        return await asyncio.wait_for(task, WAIT_S)

    return asyncio.run(main())


def test_a_service_that_cannot_be_started_stops_the_rig() -> None:
    physics, sound = free_ports(2)
    out, err = io.StringIO(), io.StringIO()
    the_rig = rig.Rig([StandIn("physics", physics, 0.0), Unstartable("sound", sound, [])], stop_timeout_s=20,
                      out=out, err=err, ready=rig.ReadyWait(WAIT_S, "127.0.0.1", time.time(), None))

    async def main() -> int:
        # no one stops this rig but itself: until the fix it waited for Ctrl-C with physics running
        return await asyncio.wait_for(the_rig.run(None), WAIT_S)

    assert asyncio.run(main()) == 1, out.getvalue() + err.getvalue()
    assert "batteur rig: cannot start sound: No such file or directory; stopping the rig\n" in err.getvalue()
    assert the_rig.procs["physics"].returncode is not None  # stopped with it


ANSWERS_THEN_EXITS = """\
import socket, sys
port, code, health = int(sys.argv[1]), int(float(sys.argv[2])), bytes.fromhex(sys.argv[3])
sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
sock.bind(("127.0.0.1", port))
_, source = sock.recvfrom(65535)
sock.sendto(health, source)  # up: it answered the rig's Hello
sys.exit(code)
"""
"""A graphics stand-in that answers the rig's first Hello with its Health, then exits with the code given in place
of :class:`StandIn`'s delay."""


@pytest.mark.parametrize(("code", "why"), [(2, " (it refused its options)"), (1, "")])
def test_graphics_failing_at_start_up_stops_the_rig_with_its_code(code: int, why: str) -> None:
    """A typo in ``--graphics-arg`` (2, argparse's exit), or a view that cannot start (1: its HTTP port taken):
    graphics exits before it was up. Until the day after 7 Dec physics and sound played on and the rig said
    "services up ... but graphics, which exited: ready"; a rig started wrong fails fast."""
    ports = free_ports(3)
    fails = f"import sys; sys.exit({code})"
    plans: list[rig.ServicePlan] = [StandIn("physics", ports[0], 0.0), StandIn("sound", ports[1], 0.0),
                                    StandIn("graphics", ports[2], 0.0, fails)]
    out, err = io.StringIO(), io.StringIO()
    the_rig = rig.Rig(plans, stop_timeout_s=20, out=out, err=err,
                      ready=rig.ReadyWait(WAIT_S, "127.0.0.1", time.time(), None))
    exit_code = run(the_rig, err, "play on without it")  # stops by itself: until the fix the test stopped it here
    said = out.getvalue() + err.getvalue()
    assert exit_code == code, said
    assert f"batteur rig: graphics exited with code {code} before it was up{why}; stopping the rig\n" in said, said
    assert "play on" not in said and "services up" not in said, said
    assert all(proc.returncode is not None for proc in the_rig.procs.values())


@pytest.mark.parametrize(("code", "plays_on"), [(0, True), (3, True), (2, False)])
def test_graphics_exiting_once_up_says_the_code_the_rig_exits_with(code: int, plays_on: bool) -> None:
    """Once up, graphics exiting leaves physics and sound playing, and the rig exits with its code at the end (0 for
    a 0: the README said "exits 1"); but for 2, a usage error, which stops the rig as before."""
    ports = free_ports(3)
    plans: list[rig.ServicePlan] = [StandIn("physics", ports[0], 0.0), StandIn("sound", ports[1], 0.0),
                                    StandIn("graphics", ports[2], float(code), ANSWERS_THEN_EXITS)]
    out, err = io.StringIO(), io.StringIO()
    the_rig = rig.Rig(plans, stop_timeout_s=20, out=out, err=err,
                      ready=rig.ReadyWait(WAIT_S, "127.0.0.1", time.time(), None))
    exit_code = run(the_rig, err, "play on without it")
    said = out.getvalue() + err.getvalue()
    assert exit_code == code, said
    will = f"; it will exit {code}: graphics failed" if code else ""
    played_on = (f"batteur rig: graphics exited with code {code}; physics, sound play on without it (Ctrl-C stops "
                 f"the rig{will})\n")
    assert (played_on in err.getvalue()) == plays_on, said
    if not plays_on:
        assert "batteur rig: graphics exited with code 2 (it refused its options); stopping the rig\n" in said, said


def test_without_a_score_a_rig_that_cannot_ask_its_services_runs_on() -> None:
    """The asking socket cannot be opened (an address not on this machine: 192.0.2.1, TEST-NET-1): with no score
    waiting on the services the rig warns and runs on, as past --ready-timeout (until the fix it stopped, exit 1,
    where before 6c221a4 a rig without --score never asked)."""
    physics = free_ports(1)[0]
    out, err = io.StringIO(), io.StringIO()
    the_rig = rig.Rig([StandIn("physics", physics, 0.0)], stop_timeout_s=20, out=out, err=err,
                      ready=rig.ReadyWait(WAIT_S, "192.0.2.1", time.time(), None))
    code = run(the_rig, err, "cannot ask the services")
    assert code == 0, out.getvalue() + err.getvalue()
    assert err.getvalue().startswith("batteur rig: warning: cannot ask the services whether they are up: "), \
        err.getvalue()
    assert "the rig runs on" in err.getvalue() and "error" not in err.getvalue(), err.getvalue()


def test_graphics_exiting_with_0_before_it_was_up_stops_the_rig_with_1() -> None:
    """Review of 95cc588: graphics ending with 0 before it answered stopped the rig, which exited 0: a script's
    ``batteur rig ... && next`` read success. Now exit 1, said."""
    ports = free_ports(3)
    plans: list[rig.ServicePlan] = [StandIn("physics", ports[0], 0.0), StandIn("sound", ports[1], 0.0),
                                    StandIn("graphics", ports[2], 0.0, "import sys; sys.exit(0)")]
    out, err = io.StringIO(), io.StringIO()
    the_rig = rig.Rig(plans, stop_timeout_s=20, out=out, err=err,
                      ready=rig.ReadyWait(WAIT_S, "127.0.0.1", time.time(), None))
    exit_code = run(the_rig, err, "play on without it")  # stops by itself
    said = out.getvalue() + err.getvalue()
    assert exit_code == 1, said
    assert ("batteur rig: graphics exited with code 0 before it was up; stopping the rig (it will exit 1: graphics "
            "ended before it was up)\n") in err.getvalue(), said
    assert "play on" not in said and "services up" not in said, said


@pytest.mark.parametrize("asking_host", ["127.0.0.1", "192.0.2.1"])
def test_without_a_score_graphics_running_past_the_ready_wait_plays_on_once_killed(asking_host: str) -> None:
    """Review of 95cc588: without ``--score`` the rig runs on past ``--ready-timeout`` (or when its asking socket
    cannot be opened: 192.0.2.1, TEST-NET-1, is not on this machine) and asks no more, so a graphics that answered
    only after it never counted as up: SIGKILLed mid-show, it stopped physics and sound ("killed by SIGKILL before it
    was up"). Now one still running when the wait ends is past its start: the others play on."""
    ports = free_ports(3)
    asked = asking_host == "127.0.0.1"
    # asked: graphics answers only 4 s after its start, past the 1 s timeout; not asked, it answers no one anyway
    plans: list[rig.ServicePlan] = [StandIn("physics", ports[0], 0.0), StandIn("sound", ports[1], 0.0),
                                    StandIn("graphics", ports[2], 4.0 if asked else 0.0)]
    out, err = io.StringIO(), io.StringIO()
    the_rig = rig.Rig(plans, stop_timeout_s=20, out=out, err=err,
                      ready=rig.ReadyWait(1.0, asking_host, time.time(), None))
    said = lambda: out.getvalue() + err.getvalue()  # noqa: E731

    async def main() -> int:
        task = asyncio.create_task(the_rig.run(None))
        if asked:
            await until(lambda: "not up within --ready-timeout" in err.getvalue() or task.done(), said)
            assert "graphics" not in the_rig.up, said()
        else:  # no line says the wait ended here: it ends at the timeout
            await until(lambda: "graphics" in the_rig.past_start or task.done(), said)
        await until(lambda: answers(ports[2], 0.5) or task.done(), said)  # running, answering (late)
        the_rig.procs["graphics"].kill()
        await until(lambda: "graphics was killed" in err.getvalue() or task.done(), said)
        assert not task.done(), said()  # until the fix: stopped, physics and sound with it
        assert all(the_rig.procs[role].returncode is None for role in ("physics", "sound")), said()
        the_rig.stopping.set()
        return await asyncio.wait_for(task, WAIT_S)

    code = asyncio.run(main())
    assert code == 1, said()  # graphics failed, said by the exit status
    assert "batteur rig: graphics was killed by SIGKILL; physics, sound play on without it (Ctrl-C stops the rig; " \
           "it will exit 1: graphics failed)\n" in err.getvalue(), said()
    assert "before it was up" not in said() and "stopping the rig" not in said(), said()
    assert all(proc.returncode is not None for proc in the_rig.procs.values())


def test_a_rig_that_cannot_ask_still_stops_for_graphics_failing_at_start_up() -> None:
    """The asking socket cannot be opened: graphics is past its start only at ``--ready-timeout`` from launch, so
    one that fails at once (its HTTP port taken: 1) still stops the rig, as when it could be asked."""
    ports = free_ports(2)
    plans: list[rig.ServicePlan] = [StandIn("physics", ports[0], 0.0),
                                    StandIn("graphics", ports[1], 0.0, "import sys; sys.exit(1)")]
    out, err = io.StringIO(), io.StringIO()
    the_rig = rig.Rig(plans, stop_timeout_s=20, out=out, err=err,
                      ready=rig.ReadyWait(WAIT_S, "192.0.2.1", time.time(), None))
    exit_code = run(the_rig, err, "play on without it")  # stops by itself
    said = out.getvalue() + err.getvalue()
    assert exit_code == 1, said
    assert "batteur rig: graphics exited with code 1 before it was up; stopping the rig\n" in err.getvalue(), said
