"""A device or a pipe given where a BVH file is read (``--skeleton-bvh /dev/null``, a FIFO) is refused, naming what
it is, where ``read_bvh`` said "no such file" of a path that is there. The commands report it as they report any
other BVH file they cannot use (``batteur render``: 1, its other bad BVH files too, README "Exit status"), and
nothing is read from it: opening a FIFO would wait for a writer."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest

from batteur import render
from common.gesture.bvh import BvhError, read_bvh

ROOT = Path(__file__).resolve().parents[2]
SCORE = ROOT / "tests" / "render" / "short_groove.txt"


@pytest.fixture
def fifo(tmp_path: Path) -> Path:
    path = tmp_path / "skeleton.bvh"
    os.mkfifo(path)
    return path


def test_a_character_device_is_named_as_such() -> None:
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)
    with pytest.raises(BvhError) as refused:
        read_bvh("/dev/null")
    assert str(refused.value) == "/dev/null: not a regular file but a character device; give a BVH file"


def test_a_pipe_is_named_as_such_and_not_opened(fifo: Path) -> None:
    with pytest.raises(BvhError) as refused:  # opening it would block: no writer
        read_bvh(fifo)
    assert str(refused.value) == f"{fifo}: not a regular file but a pipe (FIFO); give a BVH file"


def test_a_missing_file_is_still_no_such_file(tmp_path: Path) -> None:
    with pytest.raises(BvhError, match=r"missing\.bvh: no such file$"):
        read_bvh(tmp_path / "missing.bvh")


@pytest.mark.parametrize("device", ["/dev/null", "fifo"])
def test_render_reports_it_in_one_line_before_planning(device: str, fifo: Path, tmp_path: Path,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    path = str(fifo) if device == "fifo" else device
    out = tmp_path / "out"
    assert render.main([str(SCORE), "-o", str(out), "--quiet", "--skeleton-bvh", path]) == 1  # as a corrupt BVH
    err = capsys.readouterr().err.strip()
    kind = "a pipe (FIFO)" if device == "fifo" else "a character device"
    assert err == f"batteur render: error: --skeleton-bvh: {path}: not a regular file but {kind}; give a BVH file"
    assert not out.exists()


def test_the_physics_node_reports_it_in_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    from services.physics.node import main

    status = main(["--no-discovery", "--no-oscquery", "--skeleton-bvh", "/dev/null"])
    lines = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert status == 2  # the node's status for any BVH file its core refuses (a corrupt one too)
    assert lines[-1] == ("batteur physics: error: /dev/null: not a regular file but a character device; "
                         "give a BVH file"), lines
