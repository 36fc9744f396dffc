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
    assert status == 1  # an input it cannot use (README "Exit status"); until 6 Dec 2, as for a corrupt BVH
    assert lines[-1] == ("batteur physics: error: /dev/null: not a regular file but a character device; "
                         "give a BVH file"), lines


@pytest.mark.parametrize(("argv", "said"), [
    (["--skeleton-bvh", "{bad}"], "{bad}: line 2: expected ROOT, found 'broken'"),
    (["--limits-from", "{fifo}"], "{fifo}: not a regular file but a pipe (FIFO); give a BVH file"),
    (["--limits-from", "/dev/null"], "/dev/null: not a regular file but a character device; give a DeepMimic clip "
                                     "file or a shipped clip's name"),
    (["--limits-from", "{bad}"], "{bad}: line 2: expected ROOT, found 'broken'"),
])
def test_the_physics_node_refuses_a_motion_file_it_cannot_read_with_1(
        argv: list[str], said: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A corrupt skeleton, and a pipe or device given for a clip to take joint limits from: one line, status 1 (was
    2 for a corrupt file, and "no BVH file" for a pipe, "no clip '/dev/null'" for a device)."""
    from services.physics.node import main

    bad, fifo = tmp_path / "bad.bvh", tmp_path / "clip.bvh"
    bad.write_text("HIERARCHY\nbroken\n")
    os.mkfifo(fifo)
    names = {"bad": str(bad), "fifo": str(fifo)}
    status = main(["--no-discovery", "--no-oscquery", *(a.format(**names) for a in argv)])
    lines = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert status == 1
    assert lines[-1] == f"batteur physics: error: {said.format(**names)}", lines
