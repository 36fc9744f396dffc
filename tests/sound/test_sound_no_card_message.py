"""Without a sound card the node says it is not playing, and tells to record with --wav only when it is not
recording already: `batteur rig --record DIR` (sound with --wav) logged "(use --wav to record)"."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import pytest

from common.config import load_settings
from services.sound.node import make_core


def _no_card_log(wav: Path | None, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture,
                 device: str = "auto") -> str:
    monkeypatch.setattr("services.sound.node.audio_device_count", lambda: 0)
    settings = load_settings({"role": "sound", "discovery": False, "clock_master": "self"})
    extra = argparse.Namespace(kit="default", wav=wav, device=device, model="modal", block_size=256, channels=1,
                               reverb=0.0)
    caplog.set_level(logging.INFO, logger="batteur.sound")
    core = make_core(settings, extra)
    try:
        return "\n".join(f"{r.levelname} {r.getMessage()}" for r in caplog.records if "audio device" in r.getMessage())
    finally:
        for sink in core.sinks:
            discard = getattr(sink, "discard", None)
            if discard is not None:
                discard()
        core.close()


def test_a_node_recording_without_a_card_is_not_told_to_record(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                               caplog: pytest.LogCaptureFixture) -> None:
    said = _no_card_log(tmp_path / "take.wav", monkeypatch, caplog)
    assert said == "INFO no audio device found: not playing; recording only"


def test_a_node_neither_playing_nor_recording_warns_and_says_what_to_do(monkeypatch: pytest.MonkeyPatch,
                                                                        caplog: pytest.LogCaptureFixture) -> None:
    """The sound laptop of a class with no card found: a WARNING (an INFO line was all it said), naming the fixes:
    the card (--device auto), --wav to record, --device none when no sound is meant."""
    said = _no_card_log(None, monkeypatch, caplog)
    assert said.startswith("WARNING no audio device found (portaudio lists none): the strikes are not played nor "
                           "recorded."), said
    for fix in ("restart with --device auto", "record them with --wav FILE",
                "give --device none if this machine is not to play (silences this warning)"):
        assert fix in said, fix


def test_device_none_says_nothing_of_a_card(monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture) -> None:
    """--device none: no card is meant, so no warning (the way to silence it)."""
    assert _no_card_log(None, monkeypatch, caplog, device="none") == ""
