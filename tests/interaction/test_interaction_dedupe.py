"""common/dedupe.py: first copies kept, repeats dropped, bounded memory, sender restarts."""

from __future__ import annotations

import random

import pytest

from common.dedupe import Deduplicator
from common.messages import Hello, Impact
from common.messages.interaction import ImpactEnd


def impact(seq: int) -> Impact:
    return Impact(
        seq=seq, time=1.0, instrument="snare", zone="centre", r=0.2, theta=0.0, velocity=2.0,
        impulse=0.01, peak_force=800.0, duration=0.0, part="right_stick_tip",
    )  # fmt: skip


def test_keeps_the_first_copy_only() -> None:
    d = Deduplicator()
    assert [d.accept("a", s) for s in (1, 1, 2, 1, 2, 3)] == [True, False, True, False, False, True]
    assert d.stats.accepted == 3 and d.stats.duplicates == 3


def test_senders_are_independent() -> None:
    d = Deduplicator()
    assert d.accept("127.0.0.1:9000", 5) and d.accept("127.0.0.1:9001", 5)


def test_address_is_part_of_the_key_for_messages() -> None:
    d = Deduplicator()
    end = ImpactEnd(seq=3, time=1.0, instrument="snare", kind="strike", impulse=0.0, peak_force=0.0,
                    duration=0.003, part="p")  # fmt: skip
    assert d.accept_message("interaction", impact(3))
    assert d.accept_message("interaction", end)  # same seq, other address: not a copy
    assert not d.accept_message("interaction", impact(3))
    hello = Hello(role="sound", node_id="n", protocol=1, osc_port=1)
    assert d.accept_message("x", hello) and d.accept_message("x", hello)  # no seq: always accepted


def test_shuffled_copies_within_the_window_are_all_caught() -> None:
    rng = random.Random(3)
    copies = [s for s in range(2000) for _ in range(4)]
    # copies arrive out of order, but each within 50 positions of its place
    keyed = sorted(range(len(copies)), key=lambda i: i + rng.uniform(0, 50))
    d = Deduplicator(window=256)
    accepted = [copies[i] for i in keyed if d.accept("s", copies[i])]
    assert sorted(accepted) == list(range(2000))


def test_memory_is_bounded_per_sender_and_in_senders() -> None:
    d = Deduplicator(window=100, max_senders=10)
    for s in range(1000):
        d.accept("s", s)
    assert len(d._senders["s"].seen) == 100
    for n in range(50):
        d.accept(f"sender{n}", 0)
    assert len(d) == 10 and d.stats.forgotten_senders == 41


def test_a_restarted_sender_is_heard_again() -> None:
    d = Deduplicator(window=100)
    for s in range(5000, 5300):
        d.accept("s", s)
    assert d.accept("s", 0)  # far below the window: the sender's counter began again
    assert d.stats.restarts == 1
    assert not d.accept("s", 0)
    assert d.accept("s", 1)


def test_forget_drops_every_address_of_a_source() -> None:
    d = Deduplicator()
    d.accept_message("127.0.0.1:5", impact(1))
    d.forget("127.0.0.1:5")
    assert d.accept_message("127.0.0.1:5", impact(1))


def test_bad_sizes_are_refused() -> None:
    with pytest.raises(ValueError):
        Deduplicator(window=0)
