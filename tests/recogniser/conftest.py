"""Fixtures for the recogniser tests: a drum pattern rendered with a held-out kit's samples."""

from __future__ import annotations

from pathlib import Path

import pytest
import soundfile as sf

from .pattern import Pattern, render_pattern


@pytest.fixture(scope="session")
def pattern() -> Pattern:
    return render_pattern()


@pytest.fixture(scope="session")
def pattern_wav(tmp_path_factory: pytest.TempPathFactory, pattern: Pattern) -> Path:
    path = tmp_path_factory.mktemp("rec") / "pattern.wav"
    sf.write(path, pattern.audio, pattern.sample_rate, subtype="PCM_16")
    return path
