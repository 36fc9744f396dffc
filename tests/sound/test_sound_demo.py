"""The demo command renders a Groove MIDI file on the full kit into a WAV file."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from common.kit import load_kit
from services.sound.demo import DEFAULT_MIDI, impacts_from_midi, main


def test_groove_midi_becomes_impacts_on_kit_objects() -> None:
    kit = load_kit("default")
    impacts = impacts_from_midi(DEFAULT_MIDI, kit, max_seconds=4.0)
    ids = {o.id for o in kit.objects}
    assert len(impacts) > 20
    assert all(i.instrument in ids for i in impacts)
    assert {"kick", "snare", "hihat"} <= {i.instrument for i in impacts}
    assert [i.time for i in impacts] == sorted(i.time for i in impacts)


def test_demo_writes_a_listenable_stereo_wav(tmp_path: Path) -> None:
    out = tmp_path / "groove.wav"
    assert main(["-o", str(out), "--seconds", "2", "--reverb", "0.1"]) == 0
    audio, rate = sf.read(out)
    assert rate == 48000 and audio.ndim == 2 and audio.shape[1] == 2
    assert 0.05 < np.max(np.abs(audio)) <= 1.0
    assert np.all(np.isfinite(audio))


def test_broken_inputs_and_outputs_are_named_and_nothing_is_written(tmp_path: Path,
                                                                     capsys: pytest.CaptureFixture[str]) -> None:
    truncated = tmp_path / "cut.mid"
    truncated.write_bytes(DEFAULT_MIDI.read_bytes()[:60])
    not_midi = tmp_path / "notes.txt"
    not_midi.write_text("kick snare")
    out = tmp_path / "groove.wav"
    for args, says in ((["--midi", str(truncated)], "cut.mid: truncated MIDI file"),
                       (["--midi", str(not_midi)], "notes.txt: not a readable MIDI file"),
                       (["-o", str(not_midi / "g.wav")], "notes.txt is a file, not a folder"),
                       (["-o", str(tmp_path / "no" / "g.wav")], "does not exist"),
                       (["-o", str(tmp_path)], "is a directory, not a file")):
        assert main(["-o", str(out), *args]) == 2
        assert says in capsys.readouterr().err
    assert not out.exists()
