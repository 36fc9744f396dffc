"""``python -m common.score FILE`` counts in words that agree with the count: a one-note score said "1 events" (and
``--plan``'s "1 strokes")."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from common.score.__main__ import main

ONE_NOTE = "tempo 60\nmeter 1/4\nSN |x|\n"


def _output(tmp_path: Path, text: str, capsys: pytest.CaptureFixture[str], *argv: str) -> list[str]:
    path = tmp_path / "score.txt"
    path.write_text(text)
    assert main([str(path), *argv]) == 0
    return capsys.readouterr().out.splitlines()


def _agree(line: str) -> None:
    """Every "N noun" of ``line`` has the noun singular for 1, plural otherwise."""
    for count, noun in re.findall(r"\b(\d+) (events?|beats?|bars?|strokes?|knots?)\b", line):
        assert noun.endswith("s") == (int(count) != 1), line


def test_one_event_is_one_event(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    lines = _output(tmp_path, ONE_NOTE, capsys, "--plan")
    assert lines[0].split(": ", 1)[1].startswith("1 event (the last at "), lines[0]
    plan = next(line for line in lines if line.startswith("plan: "))
    assert plan.startswith("plan: 1 stroke, "), plan
    for line in lines:
        _agree(line)


def test_several_events_are_events(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    lines = _output(tmp_path, "tempo 120\nmeter 4/4\nSN |x.x.|\nBD |x...|\n", capsys)
    assert lines[0].split(": ", 1)[1].startswith("3 events (the last at "), lines[0]
    for line in lines:
        _agree(line)


def test_a_score_without_notes_says_no_limb_plays(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    lines = _output(tmp_path, "tempo 120\nmeter 4/4\nSN |....|\n", capsys)  # said "limbs: " with nothing after
    # no last event to be at: until 7 Dec "0 events (the last at 0.00 s)"
    assert lines[0].split(": ", 1)[1].startswith("0 events, "), lines[0]
    assert "limbs: none" in lines, lines


def test_midi_options_on_a_text_score_are_said_unused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "map.json").write_text('{"notes": {"25": 42}}')
    lines = _output(tmp_path, ONE_NOTE, capsys, "--drum-channels", "1", "--drum-map", str(tmp_path / "map.json"))
    said = [line for line in lines if "not used" in line]  # until 7 Dec ignored without a word
    assert said == [f"warning: {tmp_path / 'score.txt'}: --drum-channels and --drum-map not used: a text score "
                    "names its drums (they read MIDI files)"], lines
    assert not any("not used" in line for line in _output(tmp_path, ONE_NOTE, capsys))  # none given: none said
