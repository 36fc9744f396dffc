"""`/batteur/score/load /etc/passwd` was refused as "no such file in the score library" though the file exists: it
is refused because it is outside the library, and the refusal says so, the same for any path outside (existing or
not, so the refusal tells nothing about files outside)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from services.physics.core import PhysicsCore, PhysicsSettings
from services.physics.score_player import ScorePlayer, ScorePlayerError

SCORE = "tempo 100\nSD |x...|\n"


@pytest.fixture
def player(tmp_path: Path) -> Iterator[ScorePlayer]:
    core = PhysicsCore(PhysicsSettings(scene="strike", mode="live"))
    core.score_player.library = [tmp_path / "lib"]
    (tmp_path / "lib").mkdir()
    try:
        yield core.score_player
    finally:
        core.close()


def refusal(player: ScorePlayer, name: str) -> str:
    with pytest.raises(ScorePlayerError) as caught:
        player.resolve(name)
    return str(caught.value).replace(repr(name), "NAME")


@pytest.mark.parametrize("kind", ["absolute", "relative"])
def test_a_path_outside_the_library_is_refused_as_outside_whether_it_exists_or_not(
        player: ScorePlayer, tmp_path: Path, kind: str) -> None:
    (tmp_path / "there.txt").write_text(SCORE)
    there, nowhere = ((str(tmp_path / "there.txt"), str(tmp_path / "nowhere.txt")) if kind == "absolute"
                      else ("../there.txt", "../nowhere.txt"))
    said = refusal(player, there)
    assert said == (f"score NAME: outside the score library ({tmp_path / 'lib'}): only files inside it are read")
    assert refusal(player, nowhere) == said  # the same words: nothing learnt about what exists outside
    assert refusal(player, "../there") == said  # no extension: not matched by stem outside either


def test_a_missing_file_inside_the_library_is_still_no_such_file(player: ScorePlayer, tmp_path: Path) -> None:
    assert "no such file in the score library" in refusal(player, "missing.txt")
    assert "no such file in the score library" in refusal(player, str(tmp_path / "lib" / "missing.txt"))
    (tmp_path / "lib" / "groove.txt").write_text(SCORE)
    assert player.resolve(str(tmp_path / "lib" / "groove.txt")) == (tmp_path / "lib" / "groove.txt").resolve()
    assert player.resolve("groove") == (tmp_path / "lib" / "groove.txt").resolve()
