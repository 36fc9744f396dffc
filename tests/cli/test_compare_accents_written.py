"""``batteur compare``: an accent verdict only where the exercise writes accents (a clear split of its written
velocities), and an audio take's accents judged on the transcriber's compressed velocities."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from batteur.compare import dynamics
from services.recogniser import transcribe
from services.recogniser.classes import CLASS_NAMES
from services.recogniser.transcribe import DrumEvent
from tests.cli.test_compare import EXERCISE, report, run, write_take, written

START = 1.0


@pytest.mark.parametrize(("levels", "verdict"), [
    ((92, 98), False),  # a MIDI exercise's humanised levels: no accents written
    ((89, 127), True),  # a text score's x and X
    ((38, 89, 127), True),  # ghost, plain, accent: the accents are the 127s
    ((80, 82, 84, 118, 120, 122), True),  # humanised accents: two groups, many levels
])
def test_an_accent_verdict_only_where_accents_are_written(levels: tuple[int, ...], verdict: bool) -> None:
    pairs = [(w / 127, w / 127) for w in levels for _ in range(3)]
    got = dynamics(pairs)
    assert got is not None and ("accents_louder" in got) is verdict
    if verdict:
        top = max(levels)
        assert got["accent_mean"] == pytest.approx(np.mean([w for w in levels if top - w < 20]), abs=0.1)


def test_a_midi_exercise_without_accents_says_nothing_of_them(tmp_path: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    """Toms written at 92 and 98 and played at 98 and 92: no "ACCENTS NOT LOUDER"."""
    notes = [(0.25 * k, 48, 92 if k % 2 else 98) for k in range(16)]
    exercise = write_take(tmp_path / "exercise.mid", notes)
    take = write_take(tmp_path / "take.mid", [(START + t, p, 190 - v) for t, p, v in notes])
    got = report([str(exercise), str(take)], capsys)
    assert got["played"] == 16 and "accents_louder" not in got["drums"]["hightom"]["dynamics"]
    _, out, _ = run([str(exercise), str(take)], capsys)
    assert "ACCENTS" not in out and "accents" not in out


def test_an_audio_take_s_accents_are_judged_on_the_transcriber_s_scale(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """The exercise's hi-hat accents heard 8 above the rest (as the transcriber hears accents played 30 above):
    louder in a recording, barely louder in a MIDI take; the table's header says whose velocities."""
    exercise = tmp_path / "exercise.txt"
    exercise.write_text(EXERCISE, encoding="utf-8")
    notes = [(START + t, p, 90 if p == 42 and v == 127 else 82) for t, p, v in written(exercise)]
    cls = {42: "hihat_closed", 38: "snare", 36: "kick"}
    events = [DrumEvent(t, CLASS_NAMES.index(cls[p]), v, 0.9) for t, p, v in notes]
    monkeypatch.setattr(transcribe, "transcribe_file", lambda path, warn=None, **_: (events, 9.0))
    audio = tmp_path / "take.wav"
    sf.write(audio, np.zeros(4410), 44100)
    got = report([str(exercise), str(audio)], capsys)
    hihat = got["drums"]["hihat"]["dynamics"]
    assert hihat["accent_margin"] == pytest.approx(8.0, abs=0.01) and hihat["accents_louder"]
    _, out, _ = run([str(exercise), str(audio)], capsys)
    assert "dynamics (velocity as transcribed)" in out and "accents louder: 90 against 82" in out
    midi = write_take(tmp_path / "take.mid", notes)
    got = report([str(exercise), str(midi)], capsys)
    assert got["drums"]["hihat"]["dynamics"]["accents_barely_louder"]
    _, out, _ = run([str(exercise), str(midi)], capsys)
    assert "dynamics (MIDI velocity)" in out and "accents barely louder (+8)" in out
