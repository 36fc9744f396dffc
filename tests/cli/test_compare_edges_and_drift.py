"""``batteur compare``, a drummer's walkthrough's leftovers: a take's first beat played 0.3 s early or its last beat
0.25 s late is those notes played early or late (they read as missed plus extra: past the 150 ms a note is claimed
within, under the half beat a restart needs); a bar entered late after a written rest and played steadily on is
not "dragging" (its feel is judged against the entry); a 16-bar take at a steady 1.004 of the tempo is compared at
its tempo, not lined up three bars in with its last three bars "missed"."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from tests.cli.test_compare import groove, report, run, write_take, written
from tests.cli.test_compare_rest_entry import exercise as rest_exercise

START = 1.0
"""The exercise's start in the take, s."""


def take(exercise: Path, path: Path, move: Callable[[float], float]) -> Path:
    """The exercise played from :data:`START`, each written time t at ``move(t)`` (on the MIDI file's 0.5 ms)."""
    return write_take(path, [(round((START + move(t)) * 2000) / 2000, p, v) for t, p, v in written(exercise)])


@pytest.mark.parametrize(("by", "first", "says"), [
    (-0.3, True, ["bar 1, beat 1: kick played 300 ms early", "bar 1, beat 1: hihat played 300 ms early",
                  "bar 1, beat 1&: hihat played 300 ms early"]),
    (0.25, False, ["bar 8, beat 4: snare played 250 ms late", "bar 8, beat 4: hihat played 250 ms late",
                   "bar 8, beat 4&: hihat played 250 ms late"]),
    (0.2, False, ["bar 8, beat 4&: hihat played 200 ms late"]),
])
def test_a_first_beat_early_or_a_last_beat_late_is_its_notes_early_or_late(
        by: float, first: bool, says: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """8 rock bars (a beat 0.5 s); beat 1 of bar 1 (kick and hi-hat, the hi-hat on 1&) ``by`` s early, or beat 4
    of bar 8 (snare and hi-hat, the hi-hat on 4&) late: 3 notes told early or late by it, nothing missed or extra.
    Until 8 Dec 0.3 s early read 2 missed (the 1& hi-hat 50 ms early paired with the 1's) and
    0.25 s late 2 missed and 2 extra; 0.4 s early was already right (a silence past half a beat)."""
    path = tmp_path / "groove.txt"
    path.write_text(groove(8), encoding="utf-8")
    played = take(path, tmp_path / "take.mid", (lambda t: t + by if t < 0.5 - 1e-9 else t) if first
                  else (lambda t: t + by if t >= 15.5 - 1e-9 else t))
    got = report([str(path), str(played)], capsys)
    assert got["restarts"] == [] and got["rest_entries"] == []
    assert got["offset_s"] == pytest.approx(START, abs=1e-3)
    assert (got["played"], got["off_tolerance"], got["missed"], got["extra"], got["outside"]) == (101, 3, 0, 0, 0)
    assert sorted(m["played_off_by_ms"] for m in got["misses"]) == [pytest.approx(by * 1000, abs=0.6)] * 3
    _, out, _ = run([str(path), str(played)], capsys)
    for line in says:
        assert f"{line} (beyond the tolerance)" in out
    assert not [line for line in out.splitlines() if line.startswith("bar") and line.endswith((" missed", " extra"))]
    assert "came back in" not in out


@pytest.mark.parametrize("by", [0.5, -0.3, 0.1])
def test_a_bar_entered_late_after_a_rest_is_not_dragging(by: float, tmp_path: Path,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    """Two bars, two bars' rest, two bars entered ``by`` s late (- early) and played steadily on: the entry is
    said and its notes told late, but bars 5 and 6 are neither dragging nor rushed (until 8 Dec
    "bar 5: dragging, +500 ms on average"; 0.1 s late was no entry, and the take was compared at a tempo of
    122 bpm, with 7 missed, 7 extra and 2 wrong drums)."""
    path = rest_exercise(tmp_path / "rest.txt", [True, True, False, False, True, True])
    played = take(path, tmp_path / "take.mid", lambda t: t + by if t >= 8.0 - 1e-9 else t)
    got = report([str(path), str(played)], capsys)
    assert got["tempo_scale"] == 1 and got["tempo"] is None
    assert [(e["bar"], e["late_s"]) for e in got["rest_entries"]] == [(5, pytest.approx(by, abs=1e-3))]
    assert (got["played"], got["off_tolerance"], got["missed"], got["extra"]) == (26, 26, 0, 0)
    bars = {b["bar"]: b for b in got["bars"]}
    assert [(bars[b]["feel"], bars[b]["mean_ms"]) for b in (5, 6)] == [(None, pytest.approx(by * 1000, abs=0.6))] * 2
    assert [bars[b]["entry_ms"] for b in (5, 6)] == [pytest.approx(by * 1000, abs=0.6)] * 2
    assert got["beats_rushed_dragging"] == []
    _, out, _ = run([str(path), str(played)], capsys)
    assert f"bar 5: came in {abs(by):.1f} s {'late' if by > 0 else 'early'}" in out
    assert "dragging" not in out and "rushed" not in out


def test_a_bar_dragging_after_a_late_entry_is_told_against_the_entry(tmp_path: Path,
                                                                     capsys: pytest.CaptureFixture[str]) -> None:
    """Bar 5 entered 0.5 s late after the rest, bar 6 40 ms later still: bar 6 drags, by 40 ms, not 540; an entry
    0.08 s late is said in hundredths ("0.1 s" read as more than it was)."""
    path = rest_exercise(tmp_path / "rest.txt", [True, True, False, False, True, True])
    played = take(path, tmp_path / "take.mid",
                  lambda t: t + (0.5 if t >= 8.0 - 1e-9 else 0.0) + (0.04 if t >= 10.0 - 1e-9 else 0.0))
    got = report([str(path), str(played)], capsys)
    bars = {b["bar"]: b for b in got["bars"]}
    assert (bars[5]["feel"], bars[6]["feel"], bars[6]["mean_ms"]) == (None, "dragging", pytest.approx(540, abs=1))
    _, out, _ = run([str(path), str(played)], capsys)
    assert "bar 6: dragging, +40 ms on average against the entry after the rest (+500 ms)" in out
    assert "bar 5: dragging" not in out
    played = take(path, tmp_path / "small.mid", lambda t: t + 0.08 if t >= 8.0 - 1e-9 else t)
    _, out, _ = run([str(path), str(played)], capsys)
    assert "bar 5: came in 0.08 s late (0.2 beats) after the rest (bars 3-4)" in out


@pytest.mark.parametrize(("bars", "ratio"), [(16, 1.004), (16, 0.996), (14, 1.004)])
def test_a_long_take_a_little_off_tempo_is_compared_at_its_tempo_not_lined_up_bars_in(
        bars: int, ratio: float, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A repeated rock bar played steadily at ``ratio`` times the tempo drifts 0.13 s over 16 bars: lined up
    three bars in (14 bars: one), the take's first bars lay before the exercise and its last ones were "missed"
    after the take "stopped" (16 bars at 1.004: 163 of 208 played, 39 missed; no tempo said: a tempo had to
    match half as many notes again, more than there were). Now compared at the take's tempo, every note played."""
    path = tmp_path / "long.txt"
    path.write_text(groove(bars), encoding="utf-8")
    played = take(path, tmp_path / "take.mid", lambda t: t / ratio)
    got = report([str(path), str(played)], capsys)
    assert got["tempo_scale_found"] is True and got["tempo_scale"] == pytest.approx(ratio, abs=1e-4)
    assert got["offset_s"] == pytest.approx(START, abs=2e-3)
    assert (got["played"], got["missed"], got["extra"], got["outside"], got["take_stops"]) == (13 * bars, 0, 0, 0,
                                                                                                None)
    _, out, _ = run([str(path), str(played)], capsys)
    assert (f"played at about {120 * ratio:.1f} bpm, the exercise is at 120: compared at the take's tempo "
            f"(--tempo-scale {ratio:g})") in out
    assert "the take stops" not in out


WALTZ = """\
tempo 120
meter 1/4
SN |x.|
meter 3/4
HH |x.x.x.|x.x.x.|x.x.x.|x.x.x.|
SN |..x...|..x...|..x...|..x.x.|
BD |x.....|x.....|x.....|x...x.|
"""
"""A snare pick-up on the 3 and four bars of 3/4 at 120 bpm (a beat 0.5 s): 23 notes."""


def test_a_pick_up_written_as_a_full_bar_is_said_and_one_of_its_own_is_bar_0(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A 3/4 exercise's pick-up in a MIDI file of one time signature (a DAW's: its bar 1 two beats of rest, then
    the pick-up) is counted as the file writes it, the pick-up ``bar 1, beat 3``, and the report says why the bars
    are one more than the part's (until 8 Dec without a word); with a time signature of its own
    (1/4, then 3/4) it is bar 0 and nothing more is said."""
    text = tmp_path / "waltz.txt"
    text.write_text(WALTZ, encoding="utf-8")
    notes = written(text)
    own = write_take(tmp_path / "own.mid", notes, meters=[(0.0, 1, 4), (0.5, 3, 4)])
    daw = write_take(tmp_path / "daw.mid", [(t + 1.0, p, v) for t, p, v in notes], meters=[(0.0, 3, 4)])
    dropped = {(0.0, 38), (2.0, 36)}  # the pick-up's snare, the second full bar's downbeat kick
    played = write_take(tmp_path / "take.mid", [(START + t, p, v) for t, p, v in notes if (t, p) not in dropped])
    hint = "bar 1 has no note before beat 3 (of 3): if that is a pick-up, bars are counted as the exercise writes it"
    for exercise, pick_up, downbeat, said in ((daw, "bar 1, beat 3", "bar 3, beat 1", True),
                                              (own, "bar 0, beat 3", "bar 2, beat 1", False),
                                              (text, "bar 0, beat 3", "bar 2, beat 1", False)):
        _, out, _ = run([str(exercise), str(played)], capsys)
        assert f"{pick_up}: snare missed" in out and f"{downbeat}: kick missed" in out
        assert (hint in out) == said
        assert (report([str(exercise), str(played)], capsys)["pickup_in_bar_1"] is not None) == said
    # an exercise entering on beat 2 of its first bar (a rest first, not a pick-up): nothing said
    late = write_take(tmp_path / "beat2.mid", [(t + 0.5, p, v) for t, p, v in notes], meters=[(0.0, 3, 4)])
    assert report([str(late), str(played)], capsys)["pickup_in_bar_1"] is None
