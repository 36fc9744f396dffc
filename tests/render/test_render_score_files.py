"""The score file of ``batteur render`` and ``batteur evaluate``: a MIDI file's reading has its own bar on a terminal
(``reading SCORE``, before the planning bars), and a score that is not a readable file (a directory, a FIFO, a file
past the size limit, a MIDI track whose length runs past the file's end) is one line, exit status 2, nothing
written."""

from __future__ import annotations

import os
import struct
from pathlib import Path

import pytest

from batteur import evaluate, render
from common.score.events import MAX_SCORE_BYTES
from tests.test_planning_progress import interrupted_render_stderr

GROOVE = Path(__file__).parents[1] / "data" / "groove_drummer6_s3_1_rock_90_beat_4-4.mid"
"""4,626 bytes, 439 notes."""


def test_render_draws_a_reading_bar_for_a_midi_file_on_a_terminal_only(monkeypatch: pytest.MonkeyPatch,
                                                                       tmp_path: Path) -> None:
    out = tmp_path / "out"
    kilobytes = GROOVE.stat().st_size / 1024
    for args, terminal, text in interrupted_render_stderr(GROOVE, out, monkeypatch):
        if terminal and not args:
            reading = text.index(f"reading {GROOVE.name} [")
            assert reading < text.index(f"planning {GROOVE.name} (limbs) [")
            line = text[reading:].split("\n")[0]
            assert f"100% {kilobytes:.1f} kB / {kilobytes:.1f} kB" in line  # the file's size, not its notes
        else:
            assert f"reading {GROOVE.name}" not in text and "\r" not in text, args
        assert not out.exists()


def _score_files(folder: Path) -> list[tuple[Path, str]]:
    """Scores that are no readable file, each with what its message must say."""
    folder.mkdir()
    directory = folder / "folder.mid"
    directory.mkdir()
    fifo = folder / "pipe.mid"
    os.mkfifo(fifo)  # opened for reading it would wait for a writer for ever
    huge = folder / "huge.mid"
    with huge.open("wb") as f:  # sparse: past the limit without writing it
        f.truncate(MAX_SCORE_BYTES + 1)
    data = GROOVE.read_bytes()
    name, length = struct.unpack(">4sL", data[14:22])
    assert name == b"MTrk"
    past_end = folder / "past_end.mid"
    past_end.write_bytes(data[:18] + struct.pack(">L", length + 1000) + data[22:])
    return [(directory, "is a folder, not a score file"), (fifo, "not a regular file but a pipe (FIFO); give a score "
            "file"), (huge, "too large for a score"),
            (past_end, "truncated MIDI file")]


@pytest.mark.parametrize("command", ["render", "evaluate"])
def test_a_score_that_is_no_readable_file_is_one_line_and_exit_1(command: str, tmp_path: Path,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    for score, says in _score_files(tmp_path / "scores"):
        out = tmp_path / f"out-{score.stem}"
        if command == "render":
            status = render.main([str(score), "-o", str(out), "--quiet"])
        elif score.is_dir():  # evaluate takes a folder for an earlier render's: not one either
            status, says = evaluate.main([str(score), "--renders", str(out), "--quiet"]), "not a render directory"
        else:
            status = evaluate.main([str(score), "--renders", str(out), "--quiet"])
        err = capsys.readouterr().err.strip()
        assert status == 1, (score, err)  # an input it cannot use (README, "Exit status")
        assert says in err and str(score) in err and "\n" not in err and "Traceback" not in err
        assert not out.exists()
