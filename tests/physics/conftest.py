"""Fixtures shared by the physics tests."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from services.physics.core import PhysicsCore


@pytest.fixture(scope="module")
def drummer() -> Iterator[PhysicsCore]:
    """One drummer core (no poses sent) per test module: building the scene takes about a second."""
    core = PhysicsCore(scene="drummer", pose_rate_hz=0)
    yield core
    core.close()
