"""``batteur compare``: levels at or below the exercise's normal level are no accents. A snare of plain ``x`` (89)
and ghost ``g`` (38) writes no accent: its split is normal against ghost notes, judged as whether the ghosts were
played softer (until 7 Dec the backbeats read as accents, ghosts played as loud "ACCENTS NOT LOUDER: 89 against
89"); an ``X`` against ``x`` is still an accent verdict."""

from __future__ import annotations

from pathlib import Path

import pytest

from batteur.compare import dynamics, normal_level
from tests.cli.test_compare import report, run, write_take, written

START = 2.0
GHOSTS = ("tempo 100\nmeter 4/4\nHH |" + "|".join(["x.x.x.x.x.x.x.x."] * 4) + "|\nSN |"
          + "|".join(["..g.x..g.g..x..g"] * 4) + "|\nBD |" + "|".join(["x.......x.x....."] * 4) + "|\n")
"""Four bars: hi-hat eighths and kick plain, the snare two plain backbeats and four ghosts a bar (more ghosts than
plain notes on the snare: its own most common level is the ghosts')."""


@pytest.mark.parametrize(("ghost", "softer", "says"), [
    (89, False, "GHOST NOTES NOT SOFTER: 89 against 89"), (40, True, "ghost notes softer: 40 against 89"),
    (84, False, "ghost notes barely softer (-5): 84 against 89")])
def test_ghost_notes_are_judged_as_ghosts_not_the_backbeats_as_accents(
        ghost: int, softer: bool, says: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "ghosts.txt"
    path.write_text(GHOSTS, encoding="utf-8")
    notes = written(path)
    assert sorted({v for _, p, v in notes if p == 38}) == [38, 89]
    take = write_take(tmp_path / "take.mid", [(START + t, p, ghost if v == 38 else v) for t, p, v in notes])
    got = report([str(path), str(take)], capsys)
    snare = got["drums"]["snare"]["dynamics"]
    assert "accents_louder" not in snare
    assert snare["ghosts_softer"] is softer and snare["ghost_margin"] == 89 - ghost
    assert (snare["ghost_mean"], snare["others_mean"]) == (ghost, 89)
    _, out, _ = run([str(path), str(take)], capsys)
    line = next(line for line in out.splitlines() if line.startswith("snare"))
    assert says in line and "ACCENT" not in line.upper()


def test_an_accent_above_the_normal_level_is_still_judged(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The hi-hat's X (127) against x (89), played flat at 89: still "ACCENTS NOT LOUDER", ghosts or not."""
    path = tmp_path / "accents.txt"
    path.write_text(GHOSTS.replace("HH |" + "|".join(["x.x.x.x.x.x.x.x."] * 4),
                                   "HH |" + "|".join(["X.x.X.x.X.x.X.x."] * 4)), encoding="utf-8")
    take = write_take(tmp_path / "take.mid", [(START + t, p, 89) for t, p, _ in written(path)])
    got = report([str(path), str(take)], capsys)
    hihat = got["drums"]["hihat"]["dynamics"]
    assert hihat["accents_louder"] is False and (hihat["accent_mean"], hihat["others_mean"]) == (89, 89)
    _, out, _ = run([str(path), str(take)], capsys)
    assert "ACCENTS NOT LOUDER: 89 against 89" in next(line for line in out.splitlines() if line.startswith("hihat"))


def test_the_normal_level_is_the_most_common_one() -> None:
    assert normal_level([89 / 127] * 5 + [38 / 127] * 9 + [127 / 127] * 2) == 38
    assert normal_level([89 / 127] * 3 + [127 / 127] * 3) == 89  # a tie: the lower of two nearest the median
    assert normal_level([]) is None
    # a drum's own notes judged against the exercise's normal level: 89 and 38 are normal and ghost
    got = dynamics([(w / 127, w / 127) for w in (89, 38, 38)], normal=89)
    assert got is not None and "accents_louder" not in got and got["ghosts_softer"] is True
