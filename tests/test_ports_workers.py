"""The suite's test ports when it runs on several pytest-xdist workers: each worker's ports lie in its own slice
of the range below the kernel's ephemeral ports, so two workers never hand one port to two programs."""

import pytest

from tests import ports


def _ports_of(monkeypatch: pytest.MonkeyPatch, worker: str, count: str) -> list[int]:
    monkeypatch.setenv("PYTEST_XDIST_WORKER", worker)
    monkeypatch.setenv("PYTEST_XDIST_WORKER_COUNT", count)
    return [port for _ in range(40) for port in ports.free_ports(3)]


def test_two_workers_take_ports_from_disjoint_slices_below_the_ephemeral_range(
        monkeypatch: pytest.MonkeyPatch) -> None:
    first, second = _ports_of(monkeypatch, "gw0", "2"), _ports_of(monkeypatch, "gw1", "2")
    ephemeral = ports._ephemeral_low()
    assert max(first) < min(second), "worker gw0's ports should all lie below worker gw1's"
    assert ports.LOWEST_PORT <= min(first) and max(second) < ephemeral


def test_without_xdist_the_whole_range_is_used(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("PYTEST_XDIST_WORKER", raising=False)
    monkeypatch.delenv("PYTEST_XDIST_WORKER_COUNT", raising=False)
    low, high = ports._worker_slice(ports.LOWEST_PORT, ports._ephemeral_low() - 1)
    assert (low, high) == (ports.LOWEST_PORT, ports._ephemeral_low() - 1)
    assert ports._worker_slice(10000, 10999) == (10000, 10999)


def test_the_slices_of_three_workers_cover_the_range_without_overlap(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("PYTEST_XDIST_WORKER_COUNT", "3")
    slices = []
    for index in range(3):
        monkeypatch.setenv("PYTEST_XDIST_WORKER", f"gw{index}")
        slices.append(ports._worker_slice(10000, 10299))
    assert slices == [(10000, 10099), (10100, 10199), (10200, 10299)]
