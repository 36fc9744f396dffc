"""Two instruments rebuilding at once (each on its own lane of the rebuild worker) that need the same Bessel table or
grid compute it once: the second waits for the first (5 drums set to 20,000 modes at once ran 5 child interpreters
computing one table, 47.6 s against 17.7 s one after the other)."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from scipy.special import jn_zeros

from services.sound import membrane
from services.sound.rebuild_worker import RebuildWorker


def _first_call_waits(real: Callable[..., Any], calls: list[Any], release: threading.Event,
                      entered: threading.Event) -> Callable[..., Any]:
    """``real``, counting its calls; the first holds on until ``release`` (set by a second call: the work done
    twice), so the second asker comes while the first is computing."""

    def call(*args: Any) -> Any:
        calls.append(args)
        if len(calls) == 1:
            entered.set()
            release.wait(60)
        else:
            release.set()
        return real(*args)

    return call


def _release_once_the_second_asks(release: threading.Event, calls: list[Any], jobs: str) -> None:
    """Set ``release`` once the second asker waits for the first's job (or computes the same thing itself)."""
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and len(calls) < 2:
        if any(job.waiting for job in getattr(membrane, jobs, [])):
            break
        time.sleep(0.002)
    release.set()


def test_two_lanes_asking_for_the_same_table_compute_it_once(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(membrane, "_TABLES", [])
    calls: list[Any] = []
    release, entered = threading.Event(), threading.Event()
    monkeypatch.setattr(membrane, "_compute_table",
                        _first_call_waits(membrane._compute_table, calls, release, entered))  # noqa: SLF001
    worker = RebuildWorker()
    try:
        snare = worker.submit(membrane.bessel_table, 30, 12, lane="snare")
        assert entered.wait(60)
        kick = worker.submit(membrane.bessel_table, 24, 12, lane="kick")  # a smaller one: a slice of it
        _release_once_the_second_asks(release, calls, "_COMPUTING_TABLES")
        big, small = snare.result(60), kick.result(60)
    finally:
        worker.close()
    assert len(calls) == 1
    assert big.shape == (31, 12) and small.shape == (25, 12)
    assert np.array_equal(small[3], jn_zeros(3, 12))  # the same bits as computed at its own size
    assert not membrane._COMPUTING_TABLES  # noqa: SLF001


def test_two_lanes_asking_for_the_same_grid_compute_it_once(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(membrane, "_GRIDS", [])
    calls: list[Any] = []
    release, entered = threading.Event(), threading.Event()
    monkeypatch.setattr(membrane, "jv", _first_call_waits(membrane.jv, calls, release, entered))
    worker = RebuildWorker()
    try:
        snare = worker.submit(membrane.bessel_grid, 20, 40.0, lane="snare")
        assert entered.wait(60)
        kick = worker.submit(membrane.bessel_grid, 20, 40.0, lane="kick")
        _release_once_the_second_asks(release, calls, "_COMPUTING_GRIDS")
        first, second = snare.result(60), kick.result(60)
    finally:
        worker.close()
    assert len(calls) == 1 and second is first


def test_a_failed_computation_is_computed_again_by_the_one_waiting(monkeypatch: pytest.MonkeyPatch) -> None:
    """The first asker's worker closed (its child killed: Abandoned): another asking for it is not left without."""
    monkeypatch.setattr(membrane, "_TABLES", [])
    release, entered = threading.Event(), threading.Event()
    real = membrane._compute_table  # noqa: SLF001
    calls: list[Any] = []

    def fails_first(*args: Any) -> Any:
        calls.append(args)
        if len(calls) == 1:
            entered.set()
            release.wait(60)
            raise RuntimeError("abandoned")
        return real(*args)

    monkeypatch.setattr(membrane, "_compute_table", fails_first)
    failed: list[BaseException] = []

    def first() -> None:
        try:
            membrane.bessel_table(10, 5)
        except RuntimeError as exc:
            failed.append(exc)

    one = threading.Thread(target=first)
    one.start()
    assert entered.wait(60)
    got: list[np.ndarray] = []
    two = threading.Thread(target=lambda: got.append(membrane.bessel_table(10, 5)))
    two.start()
    _release_once_the_second_asks(release, calls, "_COMPUTING_TABLES")
    one.join(60)
    two.join(60)
    assert failed and got and got[0].shape == (11, 5) and len(calls) == 2
