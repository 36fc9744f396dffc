"""Progress while a MIDI file is read: ``read_midi(..., progress=)`` is told (bytes parsed, bytes in the file) as
mido parses it, the score is the same bytes with or without the callback, the callback's Ctrl-C comes through, and
the reader leaves Python's garbage collector as it found it (it pauses it while reading)."""

from __future__ import annotations

import gc
import pickle
from pathlib import Path

import pytest

from common.score import midi
from common.score.events import ScoreError
from common.score.midi import read_midi

DATA = Path(__file__).parents[1] / "data"
GROOVES = [DATA / "groove_drummer6_s3_1_rock_90_beat_4-4.mid",
           DATA / "groove_drummer1_s2_1_latin-chacarera_157_beat_3-4.mid"]
"""Shipped Groove files of 1,202 and 3,577 messages (4.6 and 13.6 kB)."""


@pytest.mark.parametrize("path", GROOVES, ids=lambda p: p.stem[:24])
def test_reading_reports_the_bytes_parsed_and_reads_the_same_score(path: Path,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(midi, "REPORT_EVERY_MESSAGES", 64)  # reports along the way on a short file
    size = path.stat().st_size
    calls: list[tuple[int, int]] = []
    reported = read_midi(path, progress=lambda done, total: calls.append((done, total)))
    assert pickle.dumps(reported) == pickle.dumps(read_midi(path))  # every event, beat and warning, bit for bit
    assert calls[0] == (0, size) and calls[-1] == (size, size)
    assert all(total == size for _, total in calls)
    done = [d for d, _ in calls]
    assert done == sorted(done) and len(calls) > 4  # forward, and along the way, not only at the ends
    assert max(b - a for a, b in zip(done, done[1:], strict=False)) < size / 4


def test_ctrl_c_in_the_progress_callback_stops_the_reading(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(midi, "REPORT_EVERY_MESSAGES", 64)

    def ctrl_c_along_the_way(done: int, total: int) -> None:
        if 0 < done < total:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):  # not turned into "not a valid Standard MIDI File"
        read_midi(GROOVES[0].read_bytes(), progress=ctrl_c_along_the_way)
    assert gc.isenabled()


def test_the_garbage_collector_is_left_as_it_was(tmp_path: Path) -> None:
    broken = tmp_path / "cut.mid"
    broken.write_bytes(GROOVES[0].read_bytes()[:200])
    assert gc.isenabled()
    read_midi(GROOVES[0])
    with pytest.raises(ScoreError, match="truncated"):
        read_midi(broken)
    assert gc.isenabled()
    gc.disable()
    try:
        read_midi(GROOVES[0])
        assert not gc.isenabled()  # a caller's choice is kept
    finally:
        gc.enable()
