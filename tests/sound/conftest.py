"""Fixtures of the sound tests (helpers live in sound_helpers.py)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from sound_helpers import one_drum_kit

from services.sound.core import SoundCore, SoundSettings


@pytest.fixture
def drum_core() -> Iterator[SoundCore]:
    """A core with one snare-sized membrane called ``drum``, 10 ms latency."""
    core = SoundCore(SoundSettings(latency=0.01), one_drum_kit())
    yield core
    core.close()
