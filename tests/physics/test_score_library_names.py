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


def test_a_name_without_its_extension_is_looked_for_in_library_order(library_player: ScorePlayer,
                                                                     tmp_path: Path) -> None:
    """As a name with its extension: the first library folder that has the file wins (``groove`` was refused as
    "several files match (groove.txt, groove.txt)" when two folders had it); several in one folder are named."""
    first, second = tmp_path / "lib", tmp_path / "lib2"
    second.mkdir()
    library_player.library = [first, second]
    for folder in (first, second):
        (folder / "groove.txt").write_text("tempo 100\nSD |x...|\n")
    (second / "solo.txt").write_text("tempo 100\nSD |x...|\n")
    assert library_player.resolve("groove.txt") == (first / "groove.txt").resolve()
    assert library_player.resolve("groove") == (first / "groove.txt").resolve()
    assert library_player.resolve("solo") == (second / "solo.txt").resolve()  # not in the first folder
    (first / "groove.mid").write_bytes(b"MThd")
    with pytest.raises(ScorePlayerError, match=r"several files in the score library match \(groove.mid, "
                                               r"groove.txt\): give the extension"):
        library_player.resolve("groove")


def test_a_file_of_the_bare_name_in_a_later_folder_does_not_beat_the_first_folders_match(
        library_player: ScorePlayer, tmp_path: Path) -> None:
    """Every folder was searched for the exact name before any for the stem: a file named ``groove`` in the second
    folder beat ``groove.txt`` in the first."""
    first, second = tmp_path / "lib", tmp_path / "lib2"
    second.mkdir()
    library_player.library = [first, second]
    (first / "groove.txt").write_text("tempo 100\nSD |x...|\n")
    (second / "groove").write_text("tempo 100\nSD |x...|\n")
    assert library_player.resolve("groove") == (first / "groove.txt").resolve()


def test_a_library_folder_given_as_a_link_reads_its_files_by_either_path(library_player: ScorePlayer,
                                                                        tmp_path: Path) -> None:
    """``--score-dir liblink`` (a link to lib): ``liblink/solo.txt`` was refused as outside the library (the name as
    written was judged against the folder the link leads to); a link in it that leads outside still is."""
    lib, link = tmp_path / "lib", tmp_path / "liblink"
    link.symlink_to(lib)
    library_player.library = [link]
    (lib / "solo.txt").write_text("tempo 100\nSD |x...|\n")
    (tmp_path / "outside.txt").write_text("tempo 100\nSD |x...|\n")
    (lib / "out.txt").symlink_to(tmp_path / "outside.txt")
    solo = (lib / "solo.txt").resolve()
    assert library_player.resolve(str(link / "solo.txt")) == solo  # was "outside the score library"
    assert library_player.resolve(str(lib / "solo.txt")) == solo  # the folder the link leads to
    assert library_player.resolve("solo.txt") == library_player.resolve("solo") == solo
    for name in (str(link / "out.txt"), "out.txt", "../outside.txt", str(link / ".." / "outside.txt"),
                 str(tmp_path / "outside.txt")):
        with pytest.raises(ScorePlayerError, match="outside the score library"):
            library_player.resolve(name)
    with pytest.raises(ScorePlayerError, match="no such file in the score library"):
        library_player.resolve("out")  # not matched by stem either
