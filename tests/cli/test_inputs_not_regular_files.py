"""Every loader of a file a user names refuses a pipe (FIFO) or a folder before opening it, in the one wording of
``common/input_file.py`` (``PATH: not a regular file but a pipe (FIFO); give ...``, ``PATH: is a folder, not ...``),
each with its own error type.

Until 7 Dec a FIFO held ``--config``, an interaction ``/config/load``, ``--model``, ``batteur wav-repair`` and a
poses file for ever (opened, it waits for a writer), and others said of it "not a file", "no such file" or
"not a regular file (a pipe or a device?)". The timeout makes a loader that opens the FIFO again fail, not hang.
"""

from __future__ import annotations

import argparse
import logging
import os
from collections.abc import Callable
from pathlib import Path

import pytest

from batteur import rig
from batteur.calibration import Calibration
from batteur.impact_log import read_impacts_csv
from batteur.tools.wav_repair import repair_wav
from common.config import ConfigFileError, read_config_file
from common.exit_status import InputError
from common.gesture.bvh import BvhError, read_bvh
from common.gesture.database import load_unit
from common.gesture.keyposes import KeyPoses
from common.kit import load_kit
from common.score.events import ScoreError
from common.score.midi import read_midi
from common.score.text import read_score
from services.graphics.sequence import PoseSequence
from services.interaction.config import FileConfigStore, load_config
from services.physics.mocap import ClipError, load_deepmimic
from services.physics.node import PhysicsNodeSettings, make_core
from services.recogniser.audio import load_audio
from services.recogniser.errors import AudioFileError, ModelError
from services.recogniser.model import load_model
from services.sound.samples import SampleBank

pytestmark = pytest.mark.timeout(60)  # a loader that opens the FIFO would wait for a writer for ever


def _metadata_beside(path: Path) -> object:
    """A gesture unit whose metadata file (``unit.json`` beside ``unit.bvh``) is ``path``."""
    return load_unit(path.with_suffix(".bvh"))


def _interaction_loads(path: Path) -> object:
    """``/batteur/interaction/config/load NAME``: a file of the configuration's folder, read by the running node."""
    return FileConfigStore(path.parent / "interaction.yaml").load(path.name)


def _rig_score(path: Path) -> None:
    rig.check_score(argparse.Namespace(score=str(path), strike_period=None, services="physics,sound"))


def _physics_score(path: Path) -> object:
    return make_core(PhysicsNodeSettings(scene="drummer", score=str(path), discovery=False), argparse.Namespace())


LOADERS: dict[str, tuple[str, Callable[[Path], object], type[BaseException]]] = {
    # name: (file name, loader, the error type it raises for a file it cannot use)
    "text score": ("score.txt", read_score, ScoreError),
    "MIDI score": ("score.mid", read_midi, ScoreError),
    "kit": ("kit.yaml", load_kit, FileNotFoundError),
    "audio to transcribe": ("take.wav", load_audio, AudioFileError),
    "recogniser model": ("model.npz", load_model, ModelError),
    "settings file (--config)": ("node.yaml", read_config_file, ConfigFileError),
    "interaction configuration": ("interaction.yaml", load_config, ValueError),
    "interaction's stored configuration": ("interaction.yaml", lambda p: FileConfigStore(p).load_or_default(),
                                           ValueError),
    "interaction /config/load": ("other.yaml", _interaction_loads, ValueError),
    "key poses": ("poses.yaml", KeyPoses.load, ValueError),
    "gesture unit metadata": ("unit.json", _metadata_beside, BvhError),
    "pose sequence (--preview)": ("poses.npz", PoseSequence.load, ValueError),
    "impact log": ("impacts.csv", read_impacts_csv, ValueError),
    "rig --score": ("score.txt", _rig_score, ValueError),
    "physics --score": ("score.txt", _physics_score, InputError),
    "BVH": ("skeleton.bvh", read_bvh, BvhError),
    "DeepMimic clip": ("clip.txt", load_deepmimic, ClipError),
    "calibration": ("cal.json", Calibration.load, ValueError),
}


@pytest.mark.parametrize("loader", list(LOADERS))
@pytest.mark.parametrize("kind", ["fifo", "folder"])
def test_a_pipe_or_a_folder_is_refused_in_the_shared_words(loader: str, kind: str, tmp_path: Path) -> None:
    name, load, error = LOADERS[loader]
    path = tmp_path / name
    if kind == "fifo":
        os.mkfifo(path)  # no writer: opened for reading, it would block for ever
    else:
        path.mkdir()
    with pytest.raises(error) as refused:
        load(path)
    said = str(refused.value)
    shared = "not a regular file but a pipe (FIFO); give " if kind == "fifo" else "is a folder, not "
    assert f"{path}: {shared}" in said and "\n" not in said, said


@pytest.mark.parametrize("kind", ["fifo", "folder"])
def test_wav_repair_refuses_a_pipe_or_a_folder_without_opening_it(kind: str, tmp_path: Path) -> None:
    # a FIFO opened to rewrite it ("r+b") does not block, but reading its header then waits for ever
    path = tmp_path / "take.wav"
    if kind == "fifo":
        os.mkfifo(path)
    else:
        path.mkdir()
    with pytest.raises(ValueError) as refused:  # its ValueErrors go without the path: main puts it before them
        repair_wav(path)
    said = "not a regular file but a pipe (FIFO); give a WAV file" if kind == "fifo" else "is a folder, not a WAV file"
    assert str(refused.value) == said


@pytest.mark.parametrize("kind", ["fifo", "folder"])
def test_a_sample_that_is_no_regular_file_is_synthesised_and_said(kind: str, tmp_path: Path,
                                                                  caplog: pytest.LogCaptureFixture) -> None:
    """The sound node plays a synthesised strike instead (as for a sample that is not there), and logs why once."""
    path = tmp_path / "snare.wav"
    if kind == "fifo":
        os.mkfifo(path)
    else:
        path.mkdir()
    bank = SampleBank(directory=tmp_path)
    with caplog.at_level(logging.WARNING, logger="services.sound.samples"):
        assert bank.get("snare") is None
        assert bank.get("snare") is None
    shared = "not a regular file but a pipe (FIFO); give a WAV sample" if kind == "fifo" else "is a folder, not a " \
        "WAV sample"
    assert [r.getMessage() for r in caplog.records] == [f"{path}: {shared}"]
    assert bank.get("missing") is None and len(caplog.records) == 1  # a sample not shipped: synthesised, in silence
