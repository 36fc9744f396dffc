"""`/batteur/score/load /etc/passwd` was refused as "no such file in the score library" though the file exists: it
is refused because it is outside the library, and the refusal says so, the same for any path outside (existing or
not, so the refusal tells nothing about files outside)."""

from __future__ import annotations

from pathlib import Path

import pytest

from services.physics.score_player import ScorePlayer, ScorePlayerError

SCORE = "tempo 100\nSD |x...|\n"


def refusal(player: ScorePlayer, name: str) -> str:
    with pytest.raises(ScorePlayerError) as caught:
        player.resolve(name)
    return str(caught.value).replace(repr(name), "NAME")


@pytest.mark.parametrize("kind", ["absolute", "relative"])
def test_a_path_outside_the_library_is_refused_as_outside_whether_it_exists_or_not(
        library_player: ScorePlayer, tmp_path: Path, kind: str) -> None:
    (tmp_path / "there.txt").write_text(SCORE)
    there, nowhere = ((str(tmp_path / "there.txt"), str(tmp_path / "nowhere.txt")) if kind == "absolute"
                      else ("../there.txt", "../nowhere.txt"))
    said = refusal(library_player, there)
    assert said == (f"score NAME: outside the score library ({tmp_path / 'lib'}): only files inside it are read")
    assert refusal(library_player, nowhere) == said  # the same words: nothing learnt about what exists outside
    assert refusal(library_player, "../there") == said  # no extension: not matched by stem outside either


def test_a_missing_file_inside_the_library_is_still_no_such_file(library_player: ScorePlayer, tmp_path: Path) -> None:
    assert "no such file in the score library" in refusal(library_player, "missing.txt")
    assert "no such file in the score library" in refusal(library_player, str(tmp_path / "lib" / "missing.txt"))
    (tmp_path / "lib" / "groove.txt").write_text(SCORE)
    assert library_player.resolve(str(tmp_path / "lib" / "groove.txt")) == (tmp_path / "lib" / "groove.txt").resolve()
    assert library_player.resolve("groove") == (tmp_path / "lib" / "groove.txt").resolve()
