"""``batteur transcribe`` given a score instead of audio, or told to write its MIDI file under an audio name."""

from __future__ import annotations

from pathlib import Path

import pytest

from services.recogniser.audio import load_audio
from services.recogniser.cli import main
from services.recogniser.errors import AudioFileError

ROOT = Path(__file__).resolve().parents[2]
MIDI = ROOT / "tests" / "data" / "groove_drummer6_s3_1_rock_90_beat_4-4.mid"


def test_a_midi_file_is_said_to_be_a_score_for_render(tmp_path: Path) -> None:
    named = tmp_path / "beat.wav"  # by its bytes, not its name
    named.write_bytes(MIDI.read_bytes())
    for path in (MIDI, named):
        with pytest.raises(AudioFileError) as err:
            load_audio(path)
        # was: "not a readable audio file (WAV, FLAC, OGG...): Error opening ...: Format not recognised."
        assert str(err.value) == f"{path}: this is a MIDI file (a score), not audio: `batteur render {path} -o DIR` " \
                                 "plays it"


def test_transcribe_of_a_midi_file_fails_in_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main([str(MIDI), "-o", str(tmp_path / "x.mid")]) == 1
    err = capsys.readouterr().err
    assert "this is a MIDI file" in err and "batteur render" in err and "Traceback" not in err
    assert not (tmp_path / "x.mid").exists()


@pytest.mark.parametrize("name", ["tt.wav", "take.flac", "out"])
def test_an_output_not_named_mid_is_refused_before_transcribing(tmp_path: Path, pattern_wav: Path, name: str,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / name
    assert main([str(pattern_wav), "-o", str(out)]) == 2  # an option's value refused
    err = capsys.readouterr().err
    assert f"error: -o {out}: the transcription is a Standard MIDI File; give a name ending in .mid or .midi" in err
    assert "notes (" not in err and not out.exists()  # was: a MIDI file written as tt.wav


def test_an_output_named_midi_in_capitals_is_written(tmp_path: Path, pattern_wav: Path) -> None:
    out = tmp_path / "take.MIDI"
    assert main([str(pattern_wav), "-o", str(out), "--quiet"]) == 0
    assert out.read_bytes()[:4] == b"MThd"
