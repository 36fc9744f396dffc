"""A score asked by name without its extension (`/batteur/score/load groove`, as the Pd panel's `bp-score` sends
a user's typing) is the one library file of that name; several are named, and nothing outside the library is
matched."""

from __future__ import annotations

from pathlib import Path

import pytest

from services.physics.score_player import ScorePlayer, ScorePlayerError


def test_a_name_without_its_extension_is_the_one_file_of_that_name(library_player: ScorePlayer, tmp_path: Path) -> None:
    (tmp_path / "lib" / "groove.txt").write_text("tempo 100\nSD |x...|\n")
    (tmp_path / "lib" / "groovy.txt").write_text("tempo 100\nSD |x...|\n")
    assert library_player.resolve("groove") == (tmp_path / "lib" / "groove.txt").resolve()  # was "no such file"
    assert library_player.resolve("groove.txt") == (tmp_path / "lib" / "groove.txt").resolve()


def test_several_files_of_that_name_are_named(library_player: ScorePlayer, tmp_path: Path) -> None:
    (tmp_path / "lib" / "a.txt").write_text("tempo 100\nSD |x...|\n")
    (tmp_path / "lib" / "a.mid").write_bytes(b"MThd")
    with pytest.raises(ScorePlayerError, match=r"several files in the score library match \(a.mid, a.txt\): give "
                                               "the extension"):
        library_player.resolve("a")


def test_a_link_out_of_the_library_is_never_matched(library_player: ScorePlayer, tmp_path: Path) -> None:
    (tmp_path / "outside.txt").write_text("tempo 100\nSD |x...|\n")
    (tmp_path / "lib" / "outside.txt").symlink_to(tmp_path / "outside.txt")
    (tmp_path / "lib" / "sub").mkdir()
    with pytest.raises(ScorePlayerError, match="no such file in the score library"):
        library_player.resolve("outside")
    with pytest.raises(ScorePlayerError, match="outside the score library"):
        library_player.resolve("../outside")
