"""Rig clock and offset estimation, with injected clocks (deterministic)."""

from __future__ import annotations

import math

import pytest

from common.clock import OffsetEstimator, RigClock, answer_ping, sample_from_pong
from common.messages import ClockPing, ClockPong, decode, encode


class FakeClock:
    def __init__(self, t: float = 0.0) -> None:
        self.t = t

    def __call__(self) -> float:
        return self.t


def test_rig_clock_counts_from_the_epoch_on_a_monotonic_base() -> None:
    wall = FakeClock(1_700_000_100.0)
    mono = FakeClock(50.0)
    clock = RigClock(epoch=1_700_000_000.0, wall=wall, monotonic=mono)
    assert clock.now() == pytest.approx(100.0)
    mono.t += 2.5
    wall.t -= 3600  # the system clock is stepped back: rig time does not care
    assert clock.now() == pytest.approx(102.5)
    clock.offset = -0.25
    assert clock.local_now() == pytest.approx(102.5)
    assert clock.now() == pytest.approx(102.25)
    assert clock.to_unix(clock.now()) == pytest.approx(1_700_000_102.5)


def test_rig_clock_default_epoch_is_now() -> None:
    clock = RigClock(wall=FakeClock(1234.5), monotonic=FakeClock(7.0))
    assert clock.epoch == 1234.5
    assert clock.now() == 0.0


def test_answer_ping_echoes_and_stamps() -> None:
    ping = ClockPing(node_id="sound-1", seq=7, t_send=12.5)
    pong = answer_ping(ping, t_receive=100.25, t_reply=100.5)
    assert (pong.node_id, pong.seq, pong.t_send, pong.t_receive, pong.t_reply) == ("sound-1", 7, 12.5, 100.25, 100.5)
    # survives the wire (rig times as int + float32 fraction)
    back = decode(encode(pong)).messages[0]
    assert isinstance(back, ClockPong)
    assert back.t_receive == pytest.approx(100.25, abs=1e-6)


def exchange(
    est: OffsetEstimator, local: float, true_offset: float, d_forward: float, d_back: float, processing: float = 0.0
) -> float:
    """Simulate one ping/pong with given one-way delays; returns the local time at the end."""
    ping = est.make_ping(local)
    pong = answer_ping(
        ping,
        t_receive=local + d_forward + true_offset,
        t_reply=local + d_forward + processing + true_offset,
    )
    pong = ClockPong.model_validate(pong.model_dump())
    end = local + d_forward + processing + d_back
    est.add_pong(pong, end)
    return end


def test_one_sample_offset_and_round_trip() -> None:
    pong = ClockPong(node_id="n", seq=0, t_send=10.0, t_receive=15.002, t_reply=15.003)
    sample = sample_from_pong(pong, t_arrive=10.005)
    # t1 - t0 = 5.002, t2 - t3 = 4.998: offset 5.0; round trip 5 ms minus 1 ms processing
    assert sample.offset == pytest.approx(5.0)
    assert sample.round_trip == pytest.approx(0.004)


def test_symmetric_delays_give_the_exact_offset() -> None:
    est = OffsetEstimator("n")
    exchange(est, 100.0, true_offset=-42.125, d_forward=0.002, d_back=0.002, processing=0.0005)
    assert est.offset == pytest.approx(-42.125, abs=1e-9)
    assert est.round_trip == pytest.approx(0.004)


def test_asymmetric_delays_are_bounded_and_narrowed_by_intersection() -> None:
    true_offset = 3.75
    est = OffsetEstimator("n", window=16, best=4)
    local = 0.0
    # forward/back delays differ from exchange to exchange; each sample alone is biased by (f - b) / 2
    delays = [(0.003, 0.001), (0.001, 0.003), (0.002, 0.0015), (0.0012, 0.0025), (0.004, 0.004), (0.02, 0.001)]
    for f, b in delays:
        local = exchange(est, local + 0.5, true_offset, f, b)
    single = sample_from_pong(
        ClockPong(node_id="n", seq=0, t_send=0.0, t_receive=0.003 + true_offset, t_reply=0.003 + true_offset), 0.004
    )
    assert abs(single.offset - true_offset) == pytest.approx(0.001)  # one sample: 1 ms off
    # the true offset lies within the reported uncertainty, which is tighter than any one sample's
    assert abs(est.offset - true_offset) <= est.uncertainty + 1e-12
    assert est.uncertainty < est.round_trip / 2
    assert abs(est.offset - true_offset) < 0.0005


def test_estimate_uses_the_smallest_round_trips_of_the_window() -> None:
    true_offset = 10.0
    est = OffsetEstimator("n", window=8, best=2)
    local = 0.0
    local = exchange(est, local, true_offset, 0.001, 0.001)
    for _ in range(5):  # congested: long and lopsided
        local = exchange(est, local + 1, true_offset, 0.100, 0.002)
    assert est.offset == pytest.approx(true_offset, abs=1e-9)
    for _ in range(8):  # the good sample slides out of the window
        local = exchange(est, local + 1, true_offset, 0.050, 0.050)
    assert len(est.samples) == 8
    assert est.offset == pytest.approx(true_offset, abs=1e-9)
    assert est.uncertainty == pytest.approx(0.050)


def test_rejects_foreign_stale_and_impossible_pongs() -> None:
    est = OffsetEstimator("me", max_round_trip_s=0.5)
    ping = est.make_ping(1.0)
    other = ClockPong(node_id="other", seq=ping.seq, t_send=1.0, t_receive=5.0, t_reply=5.0)
    assert est.add_pong(other, 1.01) is None
    unknown = ClockPong(node_id="me", seq=999, t_send=1.0, t_receive=5.0, t_reply=5.0)
    assert est.add_pong(unknown, 1.01) is None
    ping = est.make_ping(2.0)
    backwards = ClockPong(node_id="me", seq=ping.seq, t_send=2.0, t_receive=5.0, t_reply=5.5)
    assert est.add_pong(backwards, 2.1) is None  # round trip would be negative
    ping = est.make_ping(3.0)
    slow = ClockPong(node_id="me", seq=ping.seq, t_send=3.0, t_receive=5.0, t_reply=5.0)
    assert est.add_pong(slow, 4.0) is None  # 1 s round trip > 0.5 s
    assert est.rejected == 4
    assert not est.ready
    assert est.offset == 0.0 and math.isinf(est.uncertainty)


def test_a_pong_is_only_used_once() -> None:
    est = OffsetEstimator("me")
    ping = est.make_ping(0.0)
    pong = answer_ping(ping, 5.001, 5.001)
    assert est.add_pong(pong, 0.002) is not None
    assert est.add_pong(pong, 0.002) is None
    assert len(est.samples) == 1


def test_disagreeing_samples_fall_back_to_the_shortest_round_trip() -> None:
    est = OffsetEstimator("n", window=4, best=2)
    exchange(est, 0.0, 1.0, 0.001, 0.001)
    exchange(est, 1.0, 1.1, 0.002, 0.002)  # the master's clock jumped by 100 ms
    assert est.offset == pytest.approx(1.0)
    assert est.uncertainty == pytest.approx(0.001)


def test_estimator_arguments_are_checked() -> None:
    with pytest.raises(ValueError):
        OffsetEstimator("n", window=4, best=5)
