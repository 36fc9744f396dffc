"""A text score's directive that cannot be read says how to write it, not Python's complaint about it
(`could not convert string to float`, `invalid literal for int() with base 10`, `'frnch' is not a valid Grip`,
or only the value again: `cannot read 'meter 3' (3)`)."""

from __future__ import annotations

from pathlib import Path

import pytest

from common.score.events import ScoreError
from common.score.text import parse_text, read_score

PYTHON_WORDS = ("convert", "literal", "int()", "float", "valid Grip", "valid Nuance")


METER_HINT = "write meter N/D: N notes of 1/D a bar (D 1 to 64, a bar at least a 64th note), e.g. 4/4, 6/8 or 2.5/4"


@pytest.mark.parametrize(("line", "hint"), [
    ("tempo 100 bpm", "write tempo BPM: a number of beats (quarter notes) per minute, 10 to 400"),
    ("meter 3", METER_HINT),
    ("meter 0/4", METER_HINT),
    ("repeat 1.5", "write repeat N: a whole number of times, 1 or more"),
    ("rest abc", "write rest [BEATS]: a number of beats, quarter notes (without it, a bar)"),
    ("grip frnch", "write grip french or german"),
    ("nuance loud", "write nuance legato, tenuto, accent, vertical_accent or staccato"),
    ("at 1 SN loud", "write at BEAT NAME [VELOCITY, 0 to 1] [L|R]"),
])
def test_a_directive_it_cannot_read_says_how_to_write_it(line: str, hint: str) -> None:
    with pytest.raises(ScoreError) as refused:
        parse_text(f"SN |x...|\n{line}\nSN |x...|\n")
    message = str(refused.value)
    assert message == f"line 2: cannot read {line!r}: {hint}"
    assert not any(word in message for word in PYTHON_WORDS), message


def test_a_text_scores_warnings_name_its_file(tmp_path: Path) -> None:
    # as its errors and a MIDI file's warnings do: `batteur render` printed "warning: line 2: ..." of no file
    path = tmp_path / "groove.txt"
    path.write_text("tempo 120\nat 1 BD 0.5 L\n")
    assert read_score(path).warnings == [f"{path}: line 2: BD is played by a foot; the hand L is ignored"]
