"""``batteur compare`` with an audio take: a written splash (china) the transcriber has no class for but files
under its crash class is compared as the crash the strikes are heard as: the crash strikes played for it are
not extras (until 7 Dec the splash was "not compared" and its strikes counted as crash extras). The transcriber
is stood in for by the strikes it would hear (its model is tested elsewhere)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from services.recogniser import transcribe
from services.recogniser.classes import CLASS_NAMES
from services.recogniser.transcribe import DrumEvent
from tests.cli.test_compare import report, run

EXERCISE = """\
tempo 120
meter 4/4
HH |x.x.x.x.x.x.x.x.|x.x.x.x.x.x.x.x.|
SN |....x.......x...|....x.......x...|
BD |x.......x.x.....|x.......x.x.....|
SP |............x...|................|
CB |................|..x.............|
"""
"""Two bars of rock, a splash on bar 1's beat 4 and a cowbell (no class folds it in) on bar 2's beat 2."""
START = 1.0


def heard(exercise_text: str) -> list[DrumEvent]:
    """The strikes a transcriber hears for the exercise played exactly: the splash as a crash, no cowbell."""
    from common.score.text import parse_text

    cls = {"HIHATCLOSED": "hihat_closed", "SNARE": "snare", "BASS": "kick", "SPLASH": "crash"}
    return [DrumEvent(START + e.time, CLASS_NAMES.index(cls[e.event.value]), 100, 0.9)
            for e in parse_text(exercise_text).events if e.event.value in cls]


def test_a_splash_heard_as_a_crash_is_compared_as_one(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    exercise = tmp_path / "exercise.txt"
    exercise.write_text(EXERCISE, encoding="utf-8")
    take = tmp_path / "take.wav"
    sf.write(take, np.zeros(4410), 44100)
    events = heard(EXERCISE)
    monkeypatch.setattr(transcribe, "transcribe_file", lambda path, warn=None, **_: (events, 5.0))
    got = report([str(exercise), str(take)], capsys)
    assert (got["written"], got["played"], got["missed"], got["extra"]) == (27, 27, 0, 0)
    assert got["not_heard"] == {"cowbell": 1}
    assert got["compared_as"] == {"splash": {"as": "crash", "notes": 1}}
    assert got["drums"]["crash"]["played"] == 1 and got["drums"]["crash"]["extra"] == 0
    _, out, _ = run([str(exercise), str(take)], capsys)
    assert "not compared (the transcriber has no class for them): cowbell 1" in out
    assert "splash 1 as crash" in out
