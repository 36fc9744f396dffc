"""``batteur compare EXERCISE TAKE --kit NAME`` with a text exercise naming an object only that kit has (``crash2``
of double_pedal): the exercise is read with ``--kit``'s kit, as render and rig read it. Until 7 Dec it was read with
its kit line's (the default): "unknown instrument 'crash2'", nothing compared."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.cli.test_compare import START, run, write_take

EXERCISE = "tempo 120\nSN |x.x.|\ncrash2 |x...|\n"  # a bar of 4 steps at 120 bpm: snare at 0 and 1 s, crash2 at 0
CRASH2 = 57  # double_pedal's note for crash2 (its note_objects)


def test_an_exercise_naming_an_object_of_the_kit_given_is_compared(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    exercise = tmp_path / "s.txt"
    exercise.write_text(EXERCISE)
    take = write_take(tmp_path / "take.mid", [(START, 38, 100), (START, CRASH2, 100), (START + 1.0, 38, 100)])
    status, out, err = run([str(exercise), str(take), "--kit", "double_pedal", "--offset", str(START), "--json"],
                           capsys)
    assert "unknown instrument" not in err
    assert status == 0, err
    report = json.loads(out)
    assert (report["played"], report["missed"], report["extra"], report["wrong_drum"]) == (3, 0, 0, 0)


def test_without_the_kit_the_exercise_is_refused_naming_the_object(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    exercise = tmp_path / "s.txt"
    exercise.write_text(EXERCISE)
    take = write_take(tmp_path / "take.mid", [(START, 38, 100)])
    status, _, err = run([str(exercise), str(take)], capsys)
    assert status == 1 and "crash2" in err


def test_a_kit_that_cannot_be_loaded_is_named_before_the_exercise_is_read(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    exercise = tmp_path / "s.txt"
    exercise.write_text(EXERCISE)
    take = write_take(tmp_path / "take.mid", [(START, 38, 100)])
    status, _, err = run([str(exercise), str(take), "--kit", str(tmp_path / "nokit.yaml")], capsys)
    assert status == 1 and "--kit" in err and "crash2" not in err
