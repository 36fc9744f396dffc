"""What a drummer met with `batteur transcribe` (7 Dec walkthrough): -o replaced an existing MIDI file (their
exercise) without a word; the tempo written was always 120 (a 100 BPM take read as 7 bars and 24.2 beats); the
summary went to stderr, stdout empty; a 30-minute silent file printed nothing for a minute before "silent"."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import mido
import numpy as np
import pytest
import soundfile as sf

from services.recogniser.cli import main
from services.recogniser.tempo import estimate_tempo
from services.recogniser.transcribe import DrumEvent

ROOT = Path(__file__).resolve().parents[2]


def _tempo_of(path: Path) -> float:
    tempos = [m.tempo for m in mido.MidiFile(path).tracks[0] if m.type == "set_tempo"]
    assert len(tempos) == 1
    return mido.tempo2bpm(tempos[0])


# 1. an existing -o file is kept unless --overwrite

@pytest.mark.parametrize("live", [False, True])
def test_an_existing_midi_file_is_not_replaced_without_overwrite(live: bool, tmp_path: Path, pattern_wav: Path,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    exercise = tmp_path / "my_exercise.mid"
    mido.MidiFile().save(exercise)
    before = exercise.read_bytes()
    extra = ["--live", "--speed", "50", "--to", "127.0.0.1:9"] if live else []
    assert main([str(pattern_wav), "-o", str(exercise), *extra]) == 1
    err = capsys.readouterr().err
    assert err.strip() == (f"batteur transcribe: error: -o {exercise}: exists, and the transcription would replace "
                           "it: move it, give another name, or give --overwrite"), err
    assert exercise.read_bytes() == before
    assert main([str(pattern_wav), "-o", str(exercise), "--overwrite", "-q", *extra]) == 0
    assert exercise.read_bytes() != before and len(mido.MidiFile(exercise).tracks[0]) > 10
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".part")]  # written atomically


def test_dev_null_is_still_written_without_overwrite(pattern_wav: Path) -> None:
    assert main([str(pattern_wav), "-o", "/dev/null", "-q"]) == 0


# 2. the tempo is estimated from the strikes

def _groove(bpm: float, bars: int = 8, swing: float = 0.5, seed: int = 0) -> list[DrumEvent]:
    """Kick and snare on the beats, hi-hat eighths (``swing``: where the offbeat falls in the beat), a crash
    every bar, +-10 ms of a drummer's timing."""
    rng = np.random.default_rng(seed)
    beat = 60.0 / bpm
    out = []
    for i in range(bars * 4):
        t = i * beat
        out += [DrumEvent(t, 2, 90, 1.0), DrumEvent(t + swing * beat, 2, 60, 1.0),
                DrumEvent(t, 0 if i % 2 == 0 else 1, 110, 1.0)]
        if i % 4 == 0:
            out.append(DrumEvent(t, 7, 100, 1.0))
    return [DrumEvent(max(0.0, e.time + float(rng.normal(0, 0.01))), e.cls, e.velocity, e.confidence) for e in out]


@pytest.mark.parametrize(("bpm", "swing"), [(100, 0.5), (132, 0.5), (100, 2 / 3), (132, 2 / 3), (85, 0.5)])
def test_a_groove_s_tempo_is_estimated(bpm: float, swing: float) -> None:
    events = _groove(bpm, swing=swing)
    found = estimate_tempo([e.time for e in events], [e.velocity for e in events])
    assert found is not None and abs(found - bpm) <= 2, found


def test_random_or_few_strikes_give_no_tempo() -> None:
    rng = np.random.default_rng(1)
    assert estimate_tempo(np.sort(rng.uniform(0, 20, 80))) is None
    assert estimate_tempo([0.0, 0.6, 1.2, 1.8]) is None


def test_strikes_without_a_finite_time_or_weight_are_left_out() -> None:
    # a library caller's NaN or infinity raised (ValueError, OverflowError) or gave 70 bpm for a NaN weight
    events = _groove(100, swing=0.5)
    times = [e.time for e in events] + [float("nan"), float("inf")]
    weights = [e.velocity for e in events] + [90.0, 90.0]
    found = estimate_tempo(times, weights)
    assert found is not None and abs(found - 100) <= 2, found
    weights[0] = float("nan")
    found = estimate_tempo(times, weights)
    assert found is not None and abs(found - 100) <= 2, found
    with pytest.raises(ValueError, match="weights"):
        estimate_tempo([0.0, 1.0], [1.0])


def test_the_rendered_pattern_s_tempo_is_written_and_said(pattern_wav: Path, tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    """The held-out kit's test pattern is played at 100 BPM (tests/recogniser/pattern.py)."""
    out = tmp_path / "p.mid"
    assert main([str(pattern_wav), "-o", str(out)]) == 0
    said = capsys.readouterr().out
    assert abs(_tempo_of(out) - 100) <= 2, _tempo_of(out)
    assert f"tempo about {_tempo_of(out):g} bpm (estimated: --tempo BPM sets it) -> {out}" in said, said


def test_the_tempo_given_wins(pattern_wav: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "p.mid"
    assert main([str(pattern_wav), "-o", str(out), "--tempo", "96"]) == 0
    assert _tempo_of(out) == pytest.approx(96, abs=0.01)
    assert "estimated" not in capsys.readouterr().out


def test_a_take_too_short_to_tell_keeps_120_and_says_so(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from .pattern import RATE, load_sample

    hit = load_sample("snare")
    audio = np.zeros(RATE, np.float32)
    audio[RATE // 4 : RATE // 4 + len(hit)] += hit[: RATE - RATE // 4]
    wav = tmp_path / "one.wav"
    sf.write(wav, audio, RATE)
    out = tmp_path / "one.mid"
    assert main([str(wav), "-o", str(out)]) == 0
    assert _tempo_of(out) == pytest.approx(120)
    assert "tempo 120 bpm (too few or too irregular strikes to estimate one: --tempo BPM sets it)" in \
        capsys.readouterr().out


# 3. where the file went: stdout, as `batteur render`'s "wrote ..." lines

def test_the_summary_is_on_stdout_and_warnings_stay_on_stderr(pattern_wav: Path, tmp_path: Path) -> None:
    out = tmp_path / "p.mid"
    run = subprocess.run([sys.executable, "-m", "batteur", "transcribe", str(pattern_wav), "-o", str(out)],
                         capture_output=True, text=True, cwd=ROOT, check=False)
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip().endswith(f"-> {out}") and " notes (" in run.stdout, run.stdout
    assert "-> " not in run.stderr, run.stderr


# 4. a long silent file: refused after a block-wise scan that shows how far it is

def test_a_long_silent_file_shows_progress_before_it_is_refused(tmp_path: Path,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    wav = tmp_path / "silent30.wav"
    rate = 8000
    with sf.SoundFile(wav, "w", rate, 1, "PCM_16") as f:
        zeros = np.zeros(rate * 60, np.int16)
        for _ in range(30):
            f.write(zeros)
    assert main([str(wav), "-o", str(tmp_path / "s.mid")]) == 1
    err = capsys.readouterr().err
    assert f"transcribing {wav}: checking for sound 100%" in err, err
    assert err.splitlines()[-1] == f"batteur transcribe: error: {wav}: the audio is silent (peak below -70 dBFS); " \
        "nothing to transcribe", err


def test_a_long_file_with_sound_is_not_held_up_by_the_scan(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from .pattern import RATE, load_sample

    hit = load_sample("kick")
    audio = np.zeros(RATE * 70, np.float32)
    for t in np.arange(1.0, 69.0, 0.6):
        i = int(t * RATE)
        audio[i : i + len(hit)] += hit[: len(audio) - i]
    wav = tmp_path / "long.wav"
    sf.write(wav, audio, RATE)
    assert main([str(wav), "-o", str(tmp_path / "l.mid")]) == 0
    err = capsys.readouterr().err
    assert "checking for sound" not in err and "transcribing" in err, err


@pytest.mark.parametrize("kind", ["zeros", "offset", "cancelling"])
def test_the_scan_refuses_as_load_audio_does(kind: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The scan's refusal is load_audio's, word for word: a constant offset and channels that cancel included."""
    from services.recogniser.audio import load_audio
    from services.recogniser.errors import AudioFileError

    rate, seconds = 4000, 61
    noise = np.random.default_rng(0).normal(0, 0.1, rate * seconds).astype(np.float32)
    data = {"zeros": np.zeros((rate * seconds, 1), np.float32),
            "offset": np.full((rate * seconds, 1), 0.25, np.float32),
            "cancelling": np.stack([noise, -noise], axis=1)}[kind]
    wav = tmp_path / f"{kind}.wav"
    sf.write(wav, data, rate, subtype="FLOAT")
    with pytest.raises(AudioFileError) as said:
        load_audio(wav)
    assert main([str(wav), "-o", str(tmp_path / "s.mid")]) == 1
    err = capsys.readouterr().err
    assert "checking for sound 100%" in err and err.splitlines()[-1] == f"batteur transcribe: error: {said.value}", err


def test_a_summary_reader_that_went_away_is_a_quiet_stop(pattern_wav: Path, tmp_path: Path) -> None:
    """Now that the summary is on stdout, `| head -0` must stay batteur's quiet stop (batteur/cli.py), not
    "error: [Errno 32] Broken pipe" and exit 1; the MIDI file is written."""
    out = tmp_path / "p.mid"
    proc = subprocess.Popen([sys.executable, "-m", "batteur", "transcribe", str(pattern_wav), "-o", str(out)],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert proc.stdout is not None
    proc.stdout.close()
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 0 and not err.strip(), err.decode()
    assert out.is_file()
