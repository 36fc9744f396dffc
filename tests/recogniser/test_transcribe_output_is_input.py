"""``batteur transcribe x.wav -o x.wav`` is a command line that cannot be run as given: a usage error (exit 2),
as the other ``-o`` values it refuses by their name (``-o tt.wav``: not a MIDI name), with one clear line; the
recording is kept. It exited 1, the status of a file the command could not use."""

from __future__ import annotations

from pathlib import Path

import pytest

from services.recogniser.cli import main


@pytest.mark.parametrize("spelling", ["same", "dotted", "link"])
def test_writing_over_the_audio_file_is_a_usage_error(spelling: str, tmp_path: Path, pattern_wav: Path,
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    audio = tmp_path / "take.wav"
    audio.write_bytes(pattern_wav.read_bytes())
    output = {"same": audio, "dotted": tmp_path / "." / "take.wav", "link": tmp_path / "take-link.wav"}[spelling]
    if spelling == "link":
        output.symlink_to(audio)
    assert main([str(audio), "-o", str(output)]) == 2  # was 1
    lines = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert lines == [f"batteur transcribe: error: -o {output}: is the audio file to transcribe ({audio}); give the "
                     "MIDI file another name, ending in .mid or .midi"], lines
    assert audio.read_bytes() == pattern_wav.read_bytes()


def test_audio_named_like_midi_is_not_written_over_either(tmp_path: Path, pattern_wav: Path,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    """A name the MIDI file may take (.mid) does not make the recording a file it may replace."""
    audio = tmp_path / "take.mid"
    audio.write_bytes(pattern_wav.read_bytes())
    assert main([str(audio), "-o", str(audio)]) == 2
    assert "is the audio file to transcribe" in capsys.readouterr().err
    assert audio.read_bytes() == pattern_wav.read_bytes()


def test_another_existing_audio_file_is_still_a_file_it_cannot_use(tmp_path: Path, pattern_wav: Path,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    """Unchanged: -o naming another take (named .mid) is refused as a file that holds other data (1)."""
    other = tmp_path / "other.mid"
    other.write_bytes(pattern_wav.read_bytes())
    assert main([str(pattern_wav), "-o", str(other)]) == 1
    assert "exists and is not a MIDI file" in capsys.readouterr().err
