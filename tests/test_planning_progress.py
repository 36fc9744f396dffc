"""Progress while a long score is planned: ``distribute`` and ``plan_gestures`` report (notes done, notes total)
to an optional callback without changing what they return, the callback's exceptions (Ctrl-C) come through, and
``batteur render`` draws a "planning" bar for each on a terminal (nothing when stderr is not one, or --quiet)."""

from __future__ import annotations

import io
import pickle
import sys
from collections.abc import Iterator
from pathlib import Path

import mido
import pytest

from batteur import render
from batteur.progress import Progress
from common.gesture.planner import plan_gestures
from common.kit import load_kit
from common.score.events import Score
from common.score.limbs import PROGRESS_EVERY, distribute
from common.score.text import read_score

HERE = Path(__file__).parent
GROOVE = HERE / "data" / "groove_drummer6_s3_1_rock_90_beat_4-4.mid"
"""439 notes, 55 s."""
SHORT = HERE / "render" / "short_groove.txt"


def _repeated_groove(path: Path, copies: int) -> Path:
    """The Groove file played ``copies`` times in a row, as one MIDI file (a long score made quickly)."""
    source = mido.MidiFile(GROOVE)
    body = [m for m in mido.merge_tracks(source.tracks) if not (m.is_meta and m.type == "end_of_track")]
    track = mido.MidiTrack(m.copy() for _ in range(copies) for m in body)
    track.append(mido.MetaMessage("end_of_track", time=0))
    out = mido.MidiFile(type=0, ticks_per_beat=source.ticks_per_beat)
    out.tracks.append(track)
    out.save(path)
    return path


@pytest.fixture(scope="module")
def long_score(tmp_path_factory: pytest.TempPathFactory) -> Score:
    score = read_score(_repeated_groove(tmp_path_factory.mktemp("score") / "long.mid", 4))
    assert len(score.events) > 4 * PROGRESS_EVERY  # some limbs have more notes than one report's worth
    return score


def _check_calls(calls: list[tuple[int, int]], total: int, step: float = PROGRESS_EVERY) -> None:
    """Reports start at 0, end at (total, total), never go back and are at most ``step`` notes apart."""
    assert calls[0] == (0, total) and calls[-1] == (total, total)
    assert all(t == total for _, t in calls)
    done = [d for d, _ in calls]
    assert done == sorted(done)
    assert max(b - a for a, b in zip(done, done[1:], strict=False)) <= step
    assert len(calls) > 3  # reports along the way, not only at the ends


def test_limb_distribution_reports_progress_and_assigns_the_same(long_score: Score) -> None:
    kit = load_kit("default")
    calls: list[tuple[int, int]] = []
    quiet = distribute(long_score, kit)
    reported = distribute(long_score, kit, progress=lambda done, total: calls.append((done, total)))
    assert reported.notes == quiet.notes and reported.issues == quiet.issues
    # the hand assignment (most of the time) reports as it searches: every PROGRESS_EVERY stick notes, which
    # stand for a little more of the bar (its share of the time over the share of the notes)
    _check_calls(calls, len(long_score.events), step=2 * PROGRESS_EVERY)


def test_the_plan_is_bit_identical_with_a_progress_callback(long_score: Score) -> None:
    kit = load_kit("default")
    assignment = distribute(long_score, kit)
    calls: list[tuple[int, int]] = []
    quiet = plan_gestures(assignment, kit, long_score)
    reported = plan_gestures(assignment, kit, long_score, progress=lambda done, total: calls.append((done, total)))
    assert pickle.dumps(reported) == pickle.dumps(quiet)  # every knot, stroke, issue and head sample, bit for bit
    _check_calls(calls, len(assignment.notes))


def test_an_exception_in_the_progress_callback_stops_planning(long_score: Score) -> None:
    kit = load_kit("default")
    assignment = distribute(long_score, kit)

    def ctrl_c_along_the_way(done: int, total: int) -> None:
        if 0 < done < total:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        distribute(long_score, kit, progress=ctrl_c_along_the_way)
    with pytest.raises(KeyboardInterrupt):
        plan_gestures(assignment, kit, long_score, progress=ctrl_c_along_the_way)


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def interrupted_render_stderr(score: Path, out: Path,
                              monkeypatch: pytest.MonkeyPatch) -> Iterator[tuple[list[str], bool, str]]:
    """``batteur render SCORE -o OUT`` stopped (Ctrl-C) where the simulation would start, on a terminal, with
    ``--quiet`` on a terminal, and not on a terminal: (arguments, on a terminal, what it wrote to stderr) of each,
    once it exited 130."""

    def stop_before_simulating(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(render, "run_score", stop_before_simulating)
    for args, terminal in (([], True), (["--quiet"], True), ([], False)):
        stderr = _Terminal() if terminal else io.StringIO()
        monkeypatch.setattr(sys, "stderr", stderr)
        assert render.main([str(score), "-o", str(out), *args]) == 130
        yield args, terminal, stderr.getvalue()


def test_render_draws_planning_bars_on_a_terminal_only(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    notes = len(read_score(SHORT).events)
    out = tmp_path / "out"
    for args, terminal, text in interrupted_render_stderr(SHORT, out, monkeypatch):
        if terminal and not args:
            limbs = text.index(f"planning {SHORT.name} (limbs) [")
            gestures = text.index(f"planning {SHORT.name} (gestures) [")
            assert limbs < gestures
            # given up before its first step, the simulation's bar is not drawn (was: drawn full, "100%")
            assert f"rendering {SHORT.name} [" not in text
            assert f"100% {notes} notes / {notes} notes" in text  # whole notes, not 13.0
        else:
            assert f"planning {SHORT.name}" not in text and "\r" not in text, args
        assert not out.exists()


def test_ctrl_c_while_planning_exits_130_and_writes_nothing(monkeypatch: pytest.MonkeyPatch,
                                                            tmp_path: Path) -> None:
    score = _repeated_groove(tmp_path / "long.mid", 2)

    class CtrlCWhilePlanning(Progress):
        def update(self, done: float) -> None:
            if self.label.endswith("(gestures)") and 0 < done < self.total:
                raise KeyboardInterrupt
            super().update(done)

    def simulated(*args: object, **kwargs: object) -> None:
        raise AssertionError("simulated after Ctrl-C")

    monkeypatch.setattr(render, "Progress", CtrlCWhilePlanning)
    monkeypatch.setattr(render, "run_score", simulated)
    terminal = _Terminal()
    monkeypatch.setattr(sys, "stderr", terminal)
    out = tmp_path / "out"
    assert render.main([str(score), "-o", str(out)]) == 130
    text = terminal.getvalue()
    assert f"interrupted; nothing written to {out}" in text
    given_up = text.split("(gestures)")[-1].split("\n")[0]
    assert "0%" in given_up and "100%" not in given_up  # the bar ends where it stood, not drawn full
    assert not out.exists()
