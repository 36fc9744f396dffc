"""The names of a take's hidden files (``common.takes``), shared by the sound node that writes them, ``batteur
wav-repair`` that recovers them and ``batteur rig`` that points to them: built names are recognised as what
they are, and nothing else is taken for a take's part file."""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from common.takes import PART_SUFFIX, is_part, part_name, part_prefix, part_take, part_timing, parts_glob

TAKES = ["performance.wav", "take.FLAC", "batteur-20260131-201500-2.wav", "long.take.w64", "big.rf64",
         "odd [1] *?.wav", "take.aiff", "take.caf", "take.AU"]


@pytest.mark.parametrize("take", TAKES)
def test_a_part_file_names_its_take_back(tmp_path: Path, take: str) -> None:
    assert part_take(part_name(take, "abcd_123")) == take
    fd, made = tempfile.mkstemp(prefix=part_prefix(take), suffix=PART_SUFFIX, dir=tmp_path)  # as WavSink makes it
    os.close(fd)
    assert part_take(Path(made).name) == take
    assert is_part(Path(made).name)
    timing = part_timing(Path(made))
    assert (timing.parent, timing.name) == (tmp_path, Path(made).name + ".json")
    assert not is_part(timing.name)


@pytest.mark.parametrize("name", [
    "download.part",  # not a take's
    "performance.wav",  # the take itself
    ".performance.wav.abcd1234.part.json",  # a part file's timing
    ".performance.wav.json.abcd1234.part",  # the take's .json being written
    "..performance.wav.abcd1234.part.json.efgh5678.part",  # a part file's timing being written
    ".notes.txt.abcd1234.part",  # not audio a node records
    ".take.raw.abcd1234.part",  # a format the node refuses
    ".performance.json.abcd1234.part",  # performance.json being written
    ".performance.wav.part",  # no random part
    "performance.wav.abcd1234.part",  # not hidden
])
def test_other_names_are_not_part_files(name: str) -> None:
    assert part_take(name) is None
    assert not is_part(name)


def test_the_glob_finds_a_takes_part_files_and_no_other(tmp_path: Path) -> None:
    take = "odd [1] *?.wav"  # glob characters in the take's name are taken as they are
    mine = tmp_path / part_name(take, "abcd1234")
    others = [part_timing(mine), tmp_path / part_name("odd 1 x.wav", "abcd1234"),
              tmp_path / part_name("performance.wav", "abcd1234"), tmp_path / take]
    for path in [mine, *others]:
        path.touch()
    assert sorted(tmp_path.glob(parts_glob(take))) == [mine]


def test_wav_repair_still_loads_no_sound_node() -> None:
    """The names are in common/ so that the tool need not import the node (seconds to load)."""
    code = ("import sys, batteur.tools.wav_repair; "
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('services', 'numpy', 'pyo', 'soundfile')))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True,
                          cwd=Path(__file__).resolve().parents[1])
    assert done.stdout.strip() == "[]"


def test_every_format_a_part_file_can_be_for_is_one_the_node_records_into() -> None:
    """The node refuses the others (common.takes.TAKE_FORMATS), so a killed take's part is never invisible."""
    from common.takes import TAKE_FORMATS
    from services.sound.core import WAV_FORMATS

    assert {f.upper() for f in TAKE_FORMATS} <= WAV_FORMATS
    assert "json" not in TAKE_FORMATS
