"""A shipped DeepMimic clip's name (``punch``) loads that clip whatever the current folder holds, and a path that is
not a regular file is refused before anything opens it.

A folder named ``punch`` in the current folder made ``load_deepmimic('punch')`` (``--limits-from punch``) refuse
the shipped clip as "not a regular file": the check looked at the name as a path before mapping it to the clip.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from services.physics.mocap import MOTIONS_DIR, ClipError, load_deepmimic

pytestmark = pytest.mark.timeout(60)  # a pipe opened for reading would wait for a writer: fail, do not hang


def test_a_folder_named_as_a_shipped_clip_does_not_hide_it(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "punch").mkdir()
    clip = load_deepmimic("punch")
    assert clip.name == "punch" and len(clip.times) > 1


def test_a_pipe_named_as_a_shipped_clip_does_not_hide_it(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    os.mkfifo(tmp_path / "walk")
    assert load_deepmimic("walk").name == "walk"


def test_a_pipe_given_for_a_clip_file_is_refused_unopened(tmp_path: Path) -> None:
    fifo = tmp_path / "mine.txt"
    os.mkfifo(fifo)
    with pytest.raises(ClipError) as refused:
        load_deepmimic(fifo)
    assert str(refused.value) == (f"{fifo}: not a regular file but a pipe (FIFO); give a DeepMimic clip file or a "
                                  "shipped clip's name")


def test_a_folder_given_for_a_clip_file_is_named_as_a_folder(tmp_path: Path) -> None:
    folder = tmp_path / "clips"
    folder.mkdir()
    with pytest.raises(ClipError) as refused:
        load_deepmimic(folder)
    assert str(refused.value) == f"{folder}: is a folder, not a DeepMimic clip file"


def test_a_clip_file_without_a_suffix_is_read_as_a_path(tmp_path: Path) -> None:
    # a name without a suffix that no shipped clip has is the path it names (was "no clip", though it was there)
    mine = tmp_path / "mine"
    mine.write_bytes((MOTIONS_DIR / "humanoid3d_punch.txt").read_bytes())
    assert load_deepmimic(mine).name == "mine"


def test_an_unknown_name_still_lists_the_shipped_clips(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    with pytest.raises(FileNotFoundError, match=r"no clip 'moonwalk' \(shipped: .*punch"):
        load_deepmimic("moonwalk")
    with pytest.raises(FileNotFoundError, match=r"no clip 'missing\.txt' \(shipped: "):
        load_deepmimic("missing.txt")
