"""Bad files fail with a clear error; the CLI writes a MIDI file and reports problems without a traceback."""

from __future__ import annotations

from pathlib import Path

import mido
import numpy as np
import pytest
import soundfile as sf

from services.recogniser.audio import load_audio
from services.recogniser.cli import main
from services.recogniser.errors import AudioFileError, ModelError
from services.recogniser.model import load_model


def _bad_files(tmp: Path) -> dict[str, tuple[Path, str]]:
    text = tmp / "notes.wav"
    text.write_text("this is not audio\n")
    empty = tmp / "empty.wav"
    sf.write(empty, np.zeros(0, np.float32), 44100)
    silent = tmp / "silent.flac"
    sf.write(silent, np.zeros(44100, np.float32), 44100)
    truncated = tmp / "truncated.wav"
    sf.write(truncated, np.random.default_rng(0).standard_normal(44100).astype(np.float32) * 0.1, 44100)
    truncated.write_bytes(truncated.read_bytes()[:30])
    return {
        "missing": (tmp / "nope.wav", "no such file"),
        "directory": (tmp, "is a folder, not an audio file"),  # as every loader says it (common/input_file.py)
        "text": (text, "not a readable audio file"),
        "empty": (empty, "no audio"),
        "silent": (silent, "silent"),
        "truncated": (truncated, "not a readable audio file"),
    }


@pytest.mark.parametrize("kind", ["missing", "directory", "text", "empty", "silent", "truncated"])
def test_bad_file_raises_a_clear_error(tmp_path: Path, kind: str) -> None:
    path, words = _bad_files(tmp_path)[kind]
    with pytest.raises(AudioFileError, match=words) as err:
        load_audio(path)
    assert str(path) in str(err.value)


def test_too_long_file_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "long.wav"
    sf.write(path, np.full(8000 * 5, 0.1, np.float32), 8000)
    with pytest.raises(AudioFileError, match="over the limit of 2 s"):
        load_audio(path, max_duration_s=2.0)
    with pytest.raises(AudioFileError, match="5 s long, over the limit of 0.25 s"):  # was "0 s"
        load_audio(path, max_duration_s=0.25)


def test_cli_reports_bad_files_without_traceback(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for path, words in _bad_files(tmp_path).values():
        assert main([str(path), "-o", str(tmp_path / "x.mid")]) == 1
        err = capsys.readouterr().err
        assert "error:" in err and words in err and "Traceback" not in err
    assert not (tmp_path / "x.mid").exists()


def test_cli_refuses_an_unwritable_output_before_transcribing(tmp_path: Path, pattern_wav: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    a_file = tmp_path / "notes.txt"
    a_file.write_text("kick")
    for output, words in ((tmp_path / "no" / "x.mid", "folder"), (tmp_path, "is a directory, not a file"),
                          (a_file / "x.mid", "notes.txt is a file, not a folder")):
        assert main([str(pattern_wav), "-o", str(output)]) == 1
        err = capsys.readouterr().err
        assert f"error: -o {output}" in err and words in err and "notes (" not in err  # refused, not transcribed
    assert not (tmp_path / "no").exists()


def test_cli_never_replaces_a_file_that_is_not_midi(tmp_path: Path, pattern_wav: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    """-o naming an earlier take (or the model file): refused before transcribing, the file kept; an earlier
    transcription is replaced with --overwrite (without it: refused too, as `batteur render` refuses)."""
    take = tmp_path / "take2.wav"
    take.write_bytes(pattern_wav.read_bytes())
    assert main([str(pattern_wav), "-o", str(take)]) == 1
    assert "exists and is not a MIDI file" in capsys.readouterr().err
    assert take.read_bytes() == pattern_wav.read_bytes()
    out = tmp_path / "out.mid"
    assert main([str(pattern_wav), "-o", str(out)]) == 0
    first = out.read_bytes()
    assert main([str(pattern_wav), "-o", str(out), "--overwrite"]) == 0 and out.read_bytes() == first


def test_cli_writes_midi(tmp_path: Path, pattern_wav: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "pattern.mid"
    assert main([str(pattern_wav), "-o", str(out)]) == 0
    assert "notes" in capsys.readouterr().out
    notes = [m for m in mido.MidiFile(out) if m.type == "note_on" and m.velocity > 0]
    assert len(notes) > 40 and {m.note for m in notes} >= {36, 38, 42}


def test_cli_shows_progress_on_long_files(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "long.wav"
    rng = np.random.default_rng(1)
    audio = np.zeros(8000 * 70, np.float32)
    audio[:: 8000 // 2] = 0.9  # clicks twice a second, 70 s at 8 kHz
    audio += 1e-3 * rng.standard_normal(len(audio)).astype(np.float32)
    sf.write(path, audio, 8000)
    assert main([str(path), "-o", str(tmp_path / "long.mid")]) == 0
    err = capsys.readouterr().err
    assert "100%" in err and "transcribing" in err


def test_cli_usage_errors(capsys: pytest.CaptureFixture[str], pattern_wav: Path) -> None:
    with pytest.raises(SystemExit) as e:
        main([str(pattern_wav)])
    assert e.value.code == 2 and "-o/--output" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:
        main(["--help"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    assert "--live" in out and "General MIDI" in out
    for option, value in (("--tempo", "inf"), ("--tempo", "1e9"), ("--tempo", "nan"), ("--speed", "nan")):
        with pytest.raises(SystemExit) as e:  # each was a traceback from the MIDI writer or the live loop
            main([str(pattern_wav), "-o", "x.mid", option, value])
        assert e.value.code == 2 and option in capsys.readouterr().err
    for target in ("127.0.0.1", "[::1]", "127.0.0.1:0", "host:port"):  # a usage error, before the model loads
        with pytest.raises(SystemExit) as e:
            main([str(pattern_wav), "--live", "--to", target])
        assert e.value.code == 2 and "--to" in capsys.readouterr().err


def test_model_errors(tmp_path: Path) -> None:
    with pytest.raises(ModelError, match="not found"):
        load_model(tmp_path / "none.npz")
    bad = tmp_path / "bad.npz"
    np.savez(bad, meta=np.frombuffer(b'{"format": "other"}', dtype=np.uint8))
    with pytest.raises(ModelError, match="unknown model format"):
        load_model(bad)
    assert main(["x.wav", "-o", str(tmp_path / "y.mid"), "--model", str(bad)]) == 1
    text = tmp_path / "model.json"
    text.write_text('{"format": "batteur-recogniser/2"}')
    with pytest.raises(ModelError, match="not an .npz archive") as refused:
        load_model(text)
    assert "pickle" not in str(refused.value)


def test_a_model_with_nan_weights_is_refused(tmp_path: Path) -> None:
    # a diverged training run's file: loading it silently gave garbage (or no) notes for every recording
    model = load_model()
    model.offline.layers[0].w[0, 0, 0, 0] = np.nan
    broken = tmp_path / "diverged.npz"
    model.save(broken)
    with pytest.raises(ModelError, match="NaN or infinite"):
        load_model(broken)


def test_a_model_is_saved_at_exactly_its_path_and_whole(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    model = load_model()
    out = tmp_path / "model.bin"  # NumPy alone writes model.bin.npz
    model.save(out)
    assert [p.name for p in tmp_path.iterdir()] == ["model.bin"]
    assert load_model(out).offline.thresholds.tolist() == model.offline.thresholds.tolist()
    before = out.read_bytes()

    def disk_full(*args: object, **kwargs: object) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr("common.output_paths.os.replace", disk_full)
    with pytest.raises(OSError):
        model.save(out, half=True)
    assert out.read_bytes() == before and [p.name for p in tmp_path.iterdir()] == ["model.bin"]
