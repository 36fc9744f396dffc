"""A clock master restarted at the same address (a static ``--peer``: compose, two laptops with fixed addresses)
says so in its pongs (``launch``): its followers follow it at its first pong, not after four agreeing outliers;
``ClockStatus.steps`` counts the steps of rig time the node logged (master restarts), and a restart logs one
step warning even when the new master's first pong took long (deterministic, but for the loopback test)."""

from __future__ import annotations

import asyncio
import logging

import pytest

from common.clock import STEP_S, OffsetEstimator, RigClock, answer_ping
from common.messages import ClockPong, decode
from common.messages.codec import encode_raw
from tests.test_clock_qa import wire
from tests.test_clock_steps import restart_master, synced_follower
from tests.waiting import wait_for

pytestmark = pytest.mark.timeout(60)

OLD, NEW = 1111, 2222
"""Launches of the master before and after its restart."""


def exchange(est: OffsetEstimator, local: float, offset: float, launch: int, delay_s: float = 0.0005) -> ClockPong:
    """One ping answered by a master of ``launch`` ``delay_s`` each way, taken at ``local + 2 * delay_s``."""
    ping = est.make_ping(local)
    master = local + delay_s + offset
    pong = wire(answer_ping(ping, master, master, launch))
    est.add_pong(pong, local + 2 * delay_s)
    return pong


def synced(offset: float, launch: int = OLD) -> tuple[OffsetEstimator, float]:
    est = OffsetEstimator("me")
    local = 100.0
    for _ in range(8):
        local += 1.0
        exchange(est, local, offset, launch)
    assert est.offset == pytest.approx(offset, abs=1e-4) and est.launch == launch
    return est, local + 1.0


def test_a_pong_of_a_new_launch_is_followed_at_once() -> None:
    est, local = synced(offset=1000.0)
    restarts = est.restarts
    ping = est.make_ping(local)
    t = local + 0.002 + 3.0  # the new master's rig time started 997 s later; it answers a little slower
    assert est.add_pong(wire(answer_ping(ping, t, t, NEW)), local + 0.004) is not None
    assert est.offset == pytest.approx(3.0, abs=0.003)
    assert (est.launch, est.restarts, est.outliers) == (NEW, restarts + 1, 0)
    exchange(est, local + 1.0, 3.0, NEW)  # its next pongs agree
    assert est.offset == pytest.approx(3.0, abs=0.003) and len(est.samples) == 2 and est.outliers == 0


def test_a_noisy_pong_of_the_same_launch_or_one_that_says_none_is_still_an_outlier() -> None:
    """A single pong far off, of the launch in use or of none (0: a forger that does not know the field, an older
    master), moves nothing: only a launch different from the samples' is a restart."""
    est, local = synced(offset=5.0)
    for launch in (OLD, 0):
        ping = est.make_ping(local)
        t = local + 86_400.0
        assert est.add_pong(wire(answer_ping(ping, t, t, launch)), local + 0.001) is None
        local += 1.0
    assert est.offset == pytest.approx(5.0, abs=1e-4)
    assert est.outliers == 2 and est.launch == OLD


def test_a_late_pong_of_the_previous_launch_does_not_step_back() -> None:
    """The old master's answer to a ping sent before the new master first answered, arriving after that answer:
    a late pong of the previous run, not a third master."""
    est, local = synced(offset=1000.0)
    late_ping = est.make_ping(local)
    ping = est.make_ping(local + 0.1)  # fast pings
    t = local + 0.1005 + 3.0
    assert est.add_pong(wire(answer_ping(ping, t, t, NEW)), local + 0.101) is not None
    old_t = local + 0.0005 + 1000.0  # its round trip, 0.102 s, is plausible
    assert est.add_pong(wire(answer_ping(late_ping, old_t, old_t, OLD)), local + 0.102) is None
    assert est.offset == pytest.approx(3.0, abs=0.003) and est.launch == NEW


def test_a_late_pong_of_the_previous_launch_asked_after_the_new_ones_first_is_refused() -> None:
    """Pings reordered around the restart: the new master answers an earlier ping, the old one a later ping whose
    pong arrives after. Taken, it stepped rig time back to the old run and forward again (three steps, three
    warnings for one restart); a launch the estimate has left is never taken up again."""
    est, local = synced(offset=1000.0)
    restarts = est.restarts
    first, second, third = (est.make_ping(local + 0.1 * i) for i in range(3))
    t = local + 0.0005 + 3.0
    assert est.add_pong(wire(answer_ping(first, t, t, NEW)), local + 0.101) is not None
    old_t = local + 0.1005 + 1000.0
    assert est.add_pong(wire(answer_ping(second, old_t, old_t, OLD)), local + 0.102) is None
    t = local + 0.2005 + 3.0
    assert est.add_pong(wire(answer_ping(third, t, t, NEW)), local + 0.201) is not None
    assert est.offset == pytest.approx(3.0, abs=0.003)
    assert (est.launch, est.restarts) == (NEW, restarts + 1)


def test_pongs_of_older_and_newer_masters_decode() -> None:
    """``launch`` is appended: an older master's pong (without it) decodes with 0, the restart then followed
    after agreeing outliers as before; a newer master's, with arguments appended since, without them."""
    old = decode(encode_raw("/batteur/clock/pong", ["me", 3, 10, 0.5, 12, 0.25, 12, 0.5])).messages
    assert old == [ClockPong(node_id="me", seq=3, t_send=10.5, t_receive=12.25, t_reply=12.5, launch=0)]
    newer = decode(encode_raw("/batteur/clock/pong", ["me", 3, 10, 0.5, 12, 0.25, 12, 0.5, NEW, 7, 0.5])).messages
    assert newer == [ClockPong(node_id="me", seq=3, t_send=10.5, t_receive=12.25, t_reply=12.5, launch=NEW)]


def test_a_new_master_whose_first_pong_took_long_logs_one_step(caplog: pytest.LogCaptureFixture) -> None:
    """The first pong of the restarted master has a 0.4 s round trip: the estimate, the middle of its interval, is
    up to 0.2 s off; the quick pongs after narrow it, moving rig time again by more than ``STEP_S``. That is
    handed to the core (it must follow), but it is no second restart."""
    clock = RigClock(0.0, wall=lambda: 100.0, monotonic=lambda: 5.0)
    est, local = synced(offset=1000.0)
    clock.set_offset(est.offset, series=est.restarts)
    steps: list[float] = []
    with caplog.at_level(logging.INFO, logger="batteur.clock"):
        ping = est.make_ping(local)
        t = local + 0.39 + 3.0  # 0.39 s there, 0.01 s back: the sample says 3.19 +/- 0.2
        assert est.add_pong(wire(answer_ping(ping, t, t, NEW)), local + 0.4) is not None
        steps.append(clock.set_offset(est.offset, "physics", series=est.restarts))
        for _ in range(3):
            local += 1.0
            exchange(est, local, 3.0, NEW)
            steps.append(clock.set_offset(est.offset, "physics", series=est.restarts))
    assert est.offset == pytest.approx(3.0, abs=0.001)
    assert steps[0] == pytest.approx(3.19 - 1000.0, abs=0.01)
    assert steps[1] == pytest.approx(-0.19, abs=0.01) and abs(steps[1]) > STEP_S and steps[2:] == [0.0, 0.0]
    warned = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
    assert len(warned) == 1 and warned[0].startswith("rig clock stepped back 996.8 s: the clock master (physics)")
    assert (clock.steps, clock.generation) == (1, 3)  # the core follows the first sync, the restart, the narrowing


def test_each_restart_of_the_estimate_logs_its_step() -> None:
    """Two restarts in a row (the master restarted twice) are two steps, each logged and counted; the first sync
    (from a clock not synced) is neither."""
    clock = RigClock(0.0, wall=lambda: 100.0, monotonic=lambda: 5.0)
    clock.set_offset(50.0, series=1)
    clock.set_offset(50.3, series=1)  # the first sync narrowing
    clock.set_offset(10.0, series=2)
    clock.set_offset(-20.0, series=3)
    assert (clock.steps, clock.generation) == (2, 4)


def test_a_master_restarted_at_the_same_address_is_followed_at_its_first_pong() -> None:
    """Over loopback, with a static --peer: the follower steps on the restarted master's first pong (no outlier
    before it), once, and its ClockStatus counts that step."""

    async def main() -> None:
        master, remote, core, epoch = await synced_follower()
        assert master.endpoint is not None
        port = master.endpoint.port
        assert remote.clock_status().steps == 0 and remote.estimator.launch == master.clock.launch
        restarted = await restart_master(master, epoch)
        try:
            await wait_for(lambda: bool(core.stepped), timeout=10.0)
            assert remote.estimator.outliers == 0  # followed at its first pong, not after agreeing outliers
            assert remote.estimator.launch == restarted.clock.launch != master.clock.launch
            assert core.stepped[0][0] == pytest.approx(-35.0, abs=0.05)
            status = remote.clock_status()
            assert status.steps == 1 and status.master == f"static:physics:127.0.0.1:{port}"
        finally:
            await remote.stop()
            await restarted.stop()

    asyncio.run(main())
