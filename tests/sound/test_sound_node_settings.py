"""The sound node's own options (``--wav``, ``--device``, ``--model`` ...) are settings like every node setting: a
flag, a ``BATTEUR_<NAME>`` variable and a config-file key (docs/deployment.md). An OSC walkthrough found
``BATTEUR_WAV=/tmp/x.wav batteur sound`` silently recording nothing, and a config file's ``wav:`` refused with an
error naming ``BATTEUR_WAV``, a variable that did nothing. No audio device is opened here (``device: none``)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from common.config import load_settings
from services.sound.node import SoundNodeSettings, WavSink, main, make_core

BASE = ["--no-discovery", "--no-oscquery", "--clock-master", "self"]


def _shown(argv: list[str], capsys: pytest.CaptureFixture[str]) -> dict[str, object]:
    assert main([*BASE, *argv, "--show-settings"]) == 0
    settings: dict[str, object] = json.loads(capsys.readouterr().out)
    return settings


def test_the_sound_options_come_from_batteur_variables(monkeypatch: pytest.MonkeyPatch, tmp_path: Path,
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    for name, value in {"WAV": str(tmp_path / "x.wav"), "DEVICE": "none", "MODEL": "sample", "BLOCK_SIZE": "128",
                        "CHANNELS": "1", "REVERB": "0.3", "PEDAL_IMPACTS": "true", "KIT": "default"}.items():
        monkeypatch.setenv(f"BATTEUR_{name}", value)
    shown = _shown([], capsys)
    assert {k: shown[k] for k in ("wav", "device", "model", "block_size", "channels", "reverb", "pedal_impacts")} == {
        "wav": str(tmp_path / "x.wav"), "device": "none", "model": "sample", "block_size": 128, "channels": 1,
        "reverb": 0.3, "pedal_impacts": True}
    assert _shown(["--device", "auto", "--block-size", "512"], capsys)["block_size"] == 512  # a flag wins


def test_the_sound_options_come_from_a_config_file_its_sound_table_first(tmp_path: Path,
                                                                          capsys: pytest.CaptureFixture[str]) -> None:
    config = tmp_path / "rig.yaml"
    config.write_text(f"wav: {tmp_path / 'top.wav'}\ndevice: none\nsound:\n  wav: {tmp_path / 'take.wav'}\n"
                      "  block-size: 64\n")
    shown = _shown(["--config", str(config)], capsys)
    assert (shown["wav"], shown["device"], shown["block_size"]) == (str(tmp_path / "take.wav"), "none", 64)


def test_a_refused_value_names_its_flag_and_its_variable(monkeypatch: pytest.MonkeyPatch,
                                                         capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setenv("BATTEUR_DEVICE", "speaker")
    assert main([*BASE, "--show-settings"]) == 2
    err = capsys.readouterr().err
    assert "invalid setting device:" in err and "[--device / BATTEUR_DEVICE]" in err


@pytest.mark.parametrize("line", ["channels: true", "reverb: true", "block-size: false"])
def test_true_or_false_in_a_config_file_is_no_number(tmp_path: Path, line: str,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    """pydantic took ``channels: true`` as 1 (mono) and ``reverb: true`` as 1.0, silently; the flags never did."""
    config = tmp_path / "sound.yaml"
    config.write_text(line + "\n")
    assert main([*BASE, "--config", str(config), "--show-settings"]) == 2
    err = capsys.readouterr().err
    assert f"invalid setting {line.split(':')[0].replace('-', '_')}:" in err and "a number, not" in err


def test_a_wav_from_the_environment_is_recorded_to(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    take = tmp_path / "env.wav"
    monkeypatch.setenv("BATTEUR_WAV", str(take))
    monkeypatch.setenv("BATTEUR_DEVICE", "none")
    monkeypatch.setenv("BATTEUR_CHANNELS", "1")
    settings = load_settings({"discovery": False, "clock_master": "self"}, None, {"role": "sound"},
                             SoundNodeSettings)
    core = make_core(settings)
    try:
        assert core.channels == 1
        sinks = [s for s in core.sinks if isinstance(s, WavSink)]
        assert [s.path for s in sinks] == [take]
        sinks[0](np.zeros((64, 1), dtype=np.float32))  # a take of one block (an empty one writes nothing: 9fb37dc)
    finally:
        core.close()
    assert take.is_file() and take.with_name("env.wav.json").is_file()
    assert sf.info(take).frames == 64 and sf.info(take).channels == 1


def test_an_empty_wav_variable_records_nothing(monkeypatch: pytest.MonkeyPatch,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setenv("BATTEUR_WAV", "")
    assert _shown([], capsys)["wav"] is None


def test_the_help_lists_the_sound_options_variables(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["--help"])
    text = " ".join(capsys.readouterr().out.split())
    for name in ("WAV", "DEVICE", "MODEL", "BLOCK_SIZE", "CHANNELS", "REVERB", "PEDAL_IMPACTS", "KIT"):
        assert f"env BATTEUR_{name}" in text
    assert "take.wav.json" in text and "origin_rig_time_s" in text
