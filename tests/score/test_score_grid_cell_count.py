"""A grid bar whose cell count is an unlikely split of its meter (9 cells in 4/4: a typo for 8, most likely) is
played as written, equal cells over the bar, with a warning naming the line and the rule's place in
docs/score-format.md ('Cells a bar'). It was taken as a 9-tuplet without a word. Tuplets and the usual grids do
not warn."""

from __future__ import annotations

from pathlib import Path

import pytest

from batteur.demo import DEMO_GROOVE
from common.score.text import odd_cells_a_bar, parse_text, read_score

TESTS = Path(__file__).resolve().parents[1]


def _cell_warnings(text: str) -> list[str]:
    return [w for w in parse_text(text).warnings if "cells a bar" in w]


def test_nine_cells_in_four_four_warn_and_still_play_as_written() -> None:
    score = parse_text("tempo 120\nmeter 4/4\nHH |xxxxxxxxx|\nBD |x........|\n")
    assert _cell_warnings("tempo 120\nmeter 4/4\nHH |xxxxxxxxx|\nBD |x........|\n") == [
        "line 3: 9 cells a bar in 4/4: not an even split of its 4 notes, played as 9 equal cells; a typo? "
        "(docs/score-format.md, 'Cells a bar')"]
    hats = [e.time for e in score.events if e.event.value == "HIHATCLOSED"]
    assert hats == pytest.approx([k * 2.0 / 9 for k in range(9)])  # one 2 s bar in nine: not refused


def test_the_warning_names_the_block_once_and_the_meter_as_written() -> None:
    text = "tempo 120\nmeter 3/4\nHH |xxxxx|xxxxx|\nSN |x....|x....|\nrepeat 2\n"  # 5 in 3/4, two bars, repeated
    assert _cell_warnings(text) == [
        "line 3: 5 cells a bar in 3/4: not an even split of its 3 notes, played as 5 equal cells; a typo? "
        "(docs/score-format.md, 'Cells a bar')"]
    assert _cell_warnings("HH |x.x.x.x.x|\n")[0].startswith("line 1: 9 cells a bar in 4/4")  # 4/4 until a meter


@pytest.mark.parametrize(("meter", "cells"), [
    ("4/4", 16), ("4/4", 8), ("4/4", 12), ("4/4", 24), ("4/4", 6), ("4/4", 3), ("4/4", 20), ("4/4", 1),
    ("3/4", 6), ("3/4", 9), ("3/4", 12), ("3/4", 4), ("6/8", 6), ("6/8", 12), ("6/8", 4), ("6/8", 10),
    ("7/8", 7), ("7/8", 14), ("5/4", 10), ("2.5/4", 5), ("2.5/4", 10), ("12/8", 8), ("12/8", 24)])
def test_usual_grids_and_tuplets_do_not_warn(meter: str, cells: int) -> None:
    assert _cell_warnings(f"tempo 120\nmeter {meter}\nHH |{'x' * cells}|\n") == []


@pytest.mark.parametrize(("meter", "cells"), [("4/4", 9), ("4/4", 17), ("4/4", 15), ("4/4", 7), ("3/4", 8),
                                              ("7/8", 8), ("7/8", 16), ("5/4", 8), ("6/8", 7), ("2.5/4", 8)])
def test_unlikely_counts_warn(meter: str, cells: int) -> None:
    assert len(_cell_warnings(f"tempo 120\nmeter {meter}\nHH |{'x' * cells}|\n")) == 1


def test_a_meter_that_stays_fractional_is_never_odd() -> None:
    assert not odd_cells_a_bar(7, 2.3)


def test_no_shipped_or_test_score_warns() -> None:
    files = [TESTS / "render" / "short_groove.txt", TESTS / "graphics" / "tiny_score.txt"]
    assert [w for f in files for w in read_score(f).warnings if "cells a bar" in w] == []
    assert _cell_warnings(DEMO_GROOVE) == []
