"""A calibration file it cannot use is named with what is wrong, as the other inputs are: a missing file was
`not a calibration file ([Errno 2] No such file or directory: 'cal.json')`, a folder `([Errno 21] Is a
directory ...)`, a binary file Python's codec message, and a pipe was waited on for ever; and a fit written over
the calibration it was made with is written whole or not at all."""

from __future__ import annotations

import os
import resource
import signal
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from batteur.calibration import Calibration

ROOT = Path(__file__).resolve().parents[2]


def _refusal(path: Path) -> str:
    with pytest.raises(ValueError) as refused:
        Calibration.load(path)
    return str(refused.value)


def test_a_missing_calibration_file_is_named_as_missing(tmp_path: Path) -> None:
    assert _refusal(tmp_path / "cal.json") == f"{tmp_path / 'cal.json'}: no such file"


def test_a_folder_given_as_the_calibration_is_named_as_a_folder(tmp_path: Path) -> None:
    assert _refusal(tmp_path) == f"{tmp_path}: is a folder, not a calibration file (JSON)"


@pytest.mark.timeout(60)  # opened for reading, a pipe waits for a writer: fail, do not hang
def test_a_pipe_given_as_the_calibration_is_refused_unopened(tmp_path: Path) -> None:
    # was: `--calibration cal.json` on a FIFO waited for ever, where a BVH or clip file's pipe is refused at once
    fifo = tmp_path / "cal.json"
    os.mkfifo(fifo)
    assert _refusal(fifo) == f"{fifo}: not a regular file but a pipe (FIFO); give a calibration file (JSON)"


def test_a_character_device_given_as_the_calibration_is_named_as_such() -> None:
    assert _refusal(Path("/dev/null")) == ("/dev/null: not a regular file but a character device; give a "
                                           "calibration file (JSON)")


def test_a_binary_file_is_not_utf8_text(tmp_path: Path) -> None:
    path = tmp_path / "cal.json"
    path.write_bytes(b"\xff\xfe\x00binary")
    assert _refusal(path) == f"{path}: not a calibration file (not UTF-8 text (invalid start byte at byte 0))"


def test_a_calibration_file_still_loads(tmp_path: Path) -> None:
    path = tmp_path / "cal.json"
    path.write_text('{"timing_s": {"snare": 0.004}, "velocity": {}, "reference": null, "samples": {"snare": 9}}')
    assert Calibration.load(path).lag("snare") == pytest.approx(0.004)


def test_a_failed_write_keeps_the_earlier_calibration(tmp_path: Path) -> None:
    # render -> evaluate -> fit writes the new fit where the old one was (`--calibration cal.json
    # --fit-calibration cal.json`): a full disk truncated it to what fitted, losing both
    path = tmp_path / "cal.json"
    Calibration(timing={"snare": 0.004}, samples={"snare": 9}).save(path)
    before = path.read_bytes()
    bigger = "Calibration(timing={f'object{i}': 0.001 * i for i in range(200)})"
    run = subprocess.run([sys.executable, "-c", f"from batteur.calibration import Calibration; {bigger}.save("
                          f"__import__('pathlib').Path({str(path)!r}))"], cwd=ROOT, capture_output=True, text=True,
                         timeout=120, preexec_fn=_no_bigger_than(len(before) + 16))
    assert run.returncode != 0 and "File too large" in run.stderr, run.stderr
    assert path.read_bytes() == before and [p.name for p in tmp_path.iterdir()] == ["cal.json"]


def _no_bigger_than(size: int) -> Callable[[], None]:
    def limit() -> None:  # in the child: writes past `size` bytes fail with EFBIG, as on a full disk
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (size, size))
    return limit
