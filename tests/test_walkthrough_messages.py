"""One-line errors that say what is wrong and what to do, found by a walk through the command line: a NaN option,
a kit name that is a file, an output folder that cannot be made, an audio file given as a score."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Literal

import numpy as np
import pytest
import soundfile as sf
from pydantic import BaseModel, Field, ValidationError

from common.config import SettingsError, load_settings
from common.datafile import first_error
from common.kit import load_kit
from common.messages import MessageError, OscMessage
from common.messages.score import LiveNote, ScoreTransport, TempoScale
from common.output_paths import check_output_dir, file_in_the_way
from common.score.events import ScoreError
from common.score.midi import read_midi
from common.score.text import read_score

ROOT = Path(__file__).resolve().parents[1]
MIDI = ROOT / "tests" / "data" / "groove_drummer6_s3_1_rock_90_beat_4-4.mid"


class _Window(BaseModel):
    latency: float = Field(0.05, ge=0.0, le=2.0)


@pytest.mark.parametrize("value", [float("nan"), "nan", "NaN"])
def test_a_nan_is_not_called_out_of_range(value: object) -> None:
    with pytest.raises(ValidationError) as err:
        _Window(latency=value)  # type: ignore[arg-type]
    assert first_error(err.value) == "latency: must be a finite number"  # was "less than or equal to 2"


def test_a_number_out_of_range_says_its_range_and_value_plainly() -> None:
    """Was pydantic's "latency: Input should be less than or equal to 2", without the value given."""
    with pytest.raises(ValidationError) as err:
        _Window(latency=3.0)
    assert first_error(err.value) == "latency: must be at most 2, got 3"


class _Bounds(BaseModel):
    above: float = Field(gt=0.5)
    from_: int = Field(ge=-3)
    below: float = Field(lt=1e3)
    action: Literal["play", "stop"] = "play"


@pytest.mark.parametrize(("values", "said"), [
    ({"above": 0.5, "from_": 0, "below": 0}, "above: must be more than 0.5, got 0.5"),
    ({"above": 1, "from_": -4, "below": 0}, "from_: must be at least -3, got -4"),
    ({"above": 1, "from_": 0, "below": 1e3}, "below: must be less than 1000, got 1000"),
    ({"above": 1, "from_": 0, "below": 0, "action": "jump"}, "action: must be 'play' or 'stop', got 'jump'"),
])
def test_every_bound_and_choice_is_said_plainly(values: dict[str, object], said: str) -> None:
    with pytest.raises(ValidationError) as err:
        _Bounds(**values)  # type: ignore[arg-type]
    assert first_error(err.value) == said


@pytest.mark.parametrize(("message", "args", "said"), [
    (TempoScale, [5.0], "factor: must be at most 4, got 5"),
    (TempoScale, [0.125], "factor: must be at least 0.25, got 0.125"),
    (LiveNote, [1, 0.0, 200, 100, 10], "pitch: must be at most 127, got 200"),
    (ScoreTransport, ["jump", 1, 0.0, 0.0], "action: must be 'play', 'stop' or 'pause', got 'jump'"),
])
def test_an_osc_refusal_says_the_bound_and_the_value(message: type[OscMessage], args: list[object],
                                                     said: str) -> None:
    """What a node answers (PhysicsRejected, the sound's rejected ...) and ``batteur send`` prints: the decoder's
    words, from :func:`first_error` as for files and settings."""
    with pytest.raises(MessageError) as err:
        message.from_args(args)  # type: ignore[arg-type]
    assert str(err.value) == f"out_of_range: {message.ADDRESS}: {said}"


def test_a_setting_out_of_range_is_said_plainly_once() -> None:
    """The settings add the value themselves ("(got ...)"): the bound's words, no second "got"."""
    with pytest.raises(SettingsError) as err:
        load_settings({"latency_s": "9"})
    message = str(err.value)
    assert "latency_s: must be at most " in message and "Input should" not in message and message.count("got") == 1


def test_a_node_setting_given_nan_says_finite() -> None:
    with pytest.raises(SettingsError) as err:
        load_settings({"latency_s": "nan"})
    message = str(err.value)
    assert "latency_s: must be a finite number" in message and "less than" not in message
    assert "--latency-s" in message


def test_render_latency_nan_is_a_usage_error_saying_finite(tmp_path: Path) -> None:
    run = subprocess.run([sys.executable, "-m", "batteur", "render", "--latency", "nan", str(MIDI), "-o",
                          str(tmp_path / "out")], cwd=ROOT, capture_output=True, text=True, timeout=120, check=False)
    assert run.returncode == 2 and "--latency nan: must be a finite number, 0 to 2 s" in run.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("kind", ["file", "folder"])
def test_a_kit_name_that_is_a_file_or_folder_says_what_kits_are(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                                kind: str) -> None:
    monkeypatch.chdir(tmp_path)
    if kind == "file":
        Path("afile").write_text("hello\n")
    else:
        Path("afile").mkdir()
    with pytest.raises(FileNotFoundError) as err:
        load_kit("afile")
    message = str(err.value)
    assert message.startswith(f"'afile' is a {kind}, not a kit") and ".yaml or .json" in message
    assert "default" in message  # the shipped kits


def test_a_shipped_kit_name_wins_over_a_file_of_that_name(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    Path("default").write_text("hello\n")
    assert load_kit("default").name == load_kit(ROOT / "common" / "kits" / "default.yaml").name


def test_an_unknown_kit_name_is_still_no_kit_file() -> None:
    with pytest.raises(FileNotFoundError, match=r"no kit file 'nokit' \(shipped kits: "):
        load_kit("nokit")


def test_an_output_folder_the_system_refuses_names_the_option(tmp_path: Path) -> None:
    """/proc looks writable to root but makes no folders: was a bare "[Errno 2] ..." from the render."""
    with pytest.raises(ValueError, match=r"^-o /proc/nope/a: cannot create a folder in /proc \(.+\); choose another "
                       r"place$"):
        check_output_dir(Path("/proc/nope/a"), "-o")
    check_output_dir(tmp_path / "new" / "deeper", "-o")  # can be made: accepted, and nothing left behind
    assert list(tmp_path.iterdir()) == []


def test_a_file_in_the_way_of_a_folder_is_found(tmp_path: Path) -> None:
    afile = tmp_path / "afile"
    afile.write_text("x")
    assert file_in_the_way(afile / "x.wav") == afile
    assert file_in_the_way(afile / "a" / "b" / "x.wav") == afile
    assert file_in_the_way(tmp_path / "new" / "x.wav") is None


def test_sound_wav_under_a_file_says_the_folder_is_a_file(tmp_path: Path) -> None:
    afile = tmp_path / "afile"
    afile.write_text("x")
    run = subprocess.run([sys.executable, "-m", "batteur", "sound", "--wav", str(afile / "x.wav"), "--no-discovery",
                          "--device", "none"], cwd=ROOT, capture_output=True, text=True, timeout=120, check=False)
    assert run.returncode == 1, run.stderr  # an output it cannot use (README, "Exit status")
    assert f"--wav {afile / 'x.wav'}: {afile} is a file, not a folder" in run.stderr  # was "[Errno 17] File exists"
    assert "Errno" not in run.stderr and afile.read_text() == "x"


def test_an_empty_midi_file_is_called_empty(tmp_path: Path) -> None:
    empty = tmp_path / "empty.mid"
    empty.write_bytes(b"")
    for read in (read_score, read_midi):
        with pytest.raises(ScoreError) as err:
            read(empty)
        assert str(err.value) == f"{empty}: the file is empty (0 bytes), not a MIDI file"  # was "truncated"


def _audio_files(tmp: Path) -> dict[str, Path]:
    """The same short sound as WAV, FLAC, Ogg and an MP3-like file (an ID3 tag: libsndfile may not write MP3)."""
    audio = np.random.default_rng(1).uniform(-0.5, 0.5, 4800).astype(np.float32)
    files = {}
    for kind, name, fmt in (("WAV", "take.wav", "WAV"), ("FLAC", "take.flac", "FLAC"), ("Ogg", "take.ogg", "OGG")):
        sf.write(tmp / name, audio, 48000, format=fmt)
        files[kind] = tmp / name
    files["MP3"] = tmp / "take.mp3"
    files["MP3"].write_bytes(b"ID3\x04\x00\x00\x00\x00\x00\x00" + bytes(range(256)) * 4)
    return files


@pytest.mark.parametrize("kind", ["WAV", "FLAC", "Ogg", "MP3"])
def test_an_audio_file_given_as_a_score_says_to_transcribe_it(tmp_path: Path, kind: str) -> None:
    path = _audio_files(tmp_path)[kind]
    with pytest.raises(ScoreError) as err:
        read_score(path)
    assert str(err.value) == (f"{path}: this is an audio file ({kind}), not a score; to play it, transcribe it "
                              f"first: batteur transcribe {path} -o score.mid")  # was "not a text score (not UTF-8"


def test_a_wav_named_mid_says_it_is_audio(tmp_path: Path) -> None:
    named = tmp_path / "take.mid"
    named.write_bytes(_audio_files(tmp_path)["WAV"].read_bytes())
    with pytest.raises(ScoreError, match=r"this is an audio file \(WAV\), not a score; .*batteur transcribe"):
        read_score(named)


def test_other_binary_files_are_still_not_text_scores(tmp_path: Path) -> None:
    blob = tmp_path / "blob.txt"
    blob.write_bytes(b"\x00\xff\xfe binary")
    with pytest.raises(ScoreError, match=r"not a text score \(not UTF-8"):
        read_score(blob)


def test_render_of_a_wav_says_to_transcribe_it(tmp_path: Path) -> None:
    wav = _audio_files(tmp_path)["WAV"]
    run = subprocess.run([sys.executable, "-m", "batteur", "render", str(wav), "-o", str(tmp_path / "out")],
                         cwd=ROOT, capture_output=True, text=True, timeout=120, check=False)
    assert run.returncode == 1 and f"batteur transcribe {wav} -o score.mid" in run.stderr
    assert "Traceback" not in run.stderr


def test_render_to_a_folder_that_cannot_be_made_names_o() -> None:
    run = subprocess.run([sys.executable, "-m", "batteur", "render", str(MIDI), "-o", "/proc/nope"],
                         cwd=ROOT, capture_output=True, text=True, timeout=120, check=False)
    assert run.returncode == 1 and "batteur render: error: -o /proc/nope: " in run.stderr  # was "[Errno 2] ..."
    assert "Errno" not in run.stderr
