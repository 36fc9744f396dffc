"""What a user meets with unusual input: a DC offset, a truncated WAV, a full disk, a slow tempo, Ctrl-C,
live options without --live and --to hosts that cannot be reached."""

from __future__ import annotations

import asyncio
import os
import resource
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import mido
import numpy as np
import pytest
import soundfile as sf

from services.recogniser.audio import load_audio
from services.recogniser.cli import main
from services.recogniser.errors import AudioFileError
from services.recogniser.midi import write_midi
from services.recogniser.node import bind_address
from services.recogniser.transcribe import DrumEvent, transcribe_file

from .pattern import Pattern

ROOT = Path(__file__).resolve().parents[2]


def _clicks(seconds: float, rate: int = 8000) -> np.ndarray:
    """Noise-burst clicks four times a second over a faint noise floor."""
    rng = np.random.default_rng(0)
    audio = 1e-3 * rng.standard_normal(int(seconds * rate)).astype(np.float32)
    audio[:: rate // 4] = 0.9
    return audio


def test_a_dc_offset_changes_nothing(tmp_path: Path, pattern: Pattern) -> None:
    plain, shifted = tmp_path / "plain.wav", tmp_path / "dc.wav"
    sf.write(plain, pattern.audio * 0.9, pattern.sample_rate, subtype="FLOAT")
    sf.write(shifted, pattern.audio * 0.9 + 0.05, pattern.sample_rate, subtype="FLOAT")
    want, _ = transcribe_file(plain)
    got, _ = transcribe_file(shifted)  # was a kick at 0 s: the step from the padding's silence into the offset
    assert [(round(e.time, 3), e.cls) for e in got] == [(round(e.time, 3), e.cls) for e in want]


def test_a_file_of_nothing_but_a_dc_offset_is_silent(tmp_path: Path) -> None:
    path = tmp_path / "dc.wav"
    sf.write(path, np.full(44100, 0.5, np.float32), 44100)
    with pytest.raises(AudioFileError, match="silent but for a constant offset of 0.5"):  # was one kick
        load_audio(path)


def test_a_truncated_wav_is_transcribed_with_a_warning(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    whole = tmp_path / "whole.wav"
    sf.write(whole, _clicks(2.0), 8000, subtype="PCM_16")
    cut = tmp_path / "cut.wav"
    cut.write_bytes(whole.read_bytes()[: 44 + 8000 * 2])  # the header still announces 2 s; 1 s is there
    assert main([str(cut), "-o", str(tmp_path / "cut.mid")]) == 0
    err = capsys.readouterr().err
    assert f"warning: {cut}: shorter than its header says" in err and "the 1 s it holds" in err
    assert main([str(whole), "-o", str(tmp_path / "whole.mid")]) == 0
    assert "shorter than its header says" not in capsys.readouterr().err  # (8 kHz: warned of its rate alone)


def _no_bigger_than(size: int) -> Any:
    def limit() -> None:  # in the child: writes past `size` bytes fail with EFBIG, as on a full disk
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (size, size))
    return limit


def test_a_failed_write_leaves_no_partial_midi_file(tmp_path: Path, pattern_wav: Path) -> None:
    out = tmp_path / "take.mid"
    run = subprocess.run([sys.executable, "-m", "services.recogniser.cli", str(pattern_wav), "-o", str(out)],
                         cwd=ROOT, capture_output=True, text=True, timeout=120, preexec_fn=_no_bigger_than(64))
    assert run.returncode == 1, run.stderr
    assert f"error: -o {out}: cannot write the MIDI file" in run.stderr and "Traceback" not in run.stderr
    assert list(tmp_path.iterdir()) == []  # was the first 64 bytes of the file


def test_an_earlier_file_survives_a_failed_write(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    out = tmp_path / "take.mid"
    write_midi([DrumEvent(0.1, 0, 100, 0.9)], out)
    before = out.read_bytes()

    def full_disk(*args: Any) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", full_disk)
    with pytest.raises(OSError):
        write_midi([DrumEvent(0.2, 1, 90, 0.9)], out)
    assert out.read_bytes() == before and [p.name for p in tmp_path.iterdir()] == ["take.mid"]


def test_the_written_file_keeps_the_usual_permissions(tmp_path: Path) -> None:
    old = os.umask(0o022)
    try:
        out = write_midi([DrumEvent(0.1, 0, 100, 0.9)], tmp_path / "take.mid")
    finally:
        os.umask(old)
    assert out.stat().st_mode & 0o777 == 0o644  # not the temporary file's 0o600


@pytest.mark.parametrize("bpm", [10.0, 33.3, 119.0, 120.0, 1000.0])
def test_times_are_exact_at_any_tempo(tmp_path: Path, bpm: float) -> None:
    events = [DrumEvent(t, 0, 100, 0.9) for t in (0.0063, 0.2571, 1.0019, 7.4447)]
    t, ons = 0.0, []
    for msg in mido.MidiFile(write_midi(events, tmp_path / "x.mid", tempo_bpm=bpm)):
        t += msg.time
        if msg.type == "note_on" and msg.velocity > 0:
            ons.append(t)
    assert np.max(np.abs(np.array(ons) - [e.time for e in events])) <= 0.00053  # half a tick; was 6 ms at 10 BPM


@pytest.mark.parametrize("extra", [["--to", "127.0.0.1:9900"], ["--speed", "4"], ["--seconds", "3"]])
def test_live_options_without_live_are_refused(capsys: pytest.CaptureFixture[str], pattern_wav: Path,
                                               extra: list[str]) -> None:
    with pytest.raises(SystemExit) as e:  # was ignored: a forgotten --live sent nothing, silently
        main([str(pattern_wav), "-o", "x.mid", *extra])
    assert e.value.code == 2 and f"{extra[0]} needs --live" in capsys.readouterr().err


def test_a_host_that_does_not_resolve_is_refused_before_playing(
        tmp_path: Path, pattern_wav: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    real = socket.getaddrinfo

    def getaddrinfo(host: Any, *args: Any, **kwargs: Any) -> Any:
        if host == "drums.invalid":
            raise socket.gaierror(socket.EAI_NONAME, "Name or service not known")
        return real(host, *args, **kwargs)

    monkeypatch.setattr(socket, "getaddrinfo", getaddrinfo)
    out = tmp_path / "heard.mid"
    # was exit 0, "N hits sent to drums.invalid:9900", every hit dropped
    assert main([str(pattern_wav), "--live", "--speed", "50", "--to", "drums.invalid:9900", "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert "error: --to drums.invalid:9900: cannot resolve host 'drums.invalid'" in err and "hits sent" not in err
    assert not out.exists()


def test_hits_are_sent_from_an_address_that_reaches_the_targets() -> None:
    assert bind_address([("127.0.0.1", 9900)]) == "127.0.0.1"  # local only: nothing listens on the network
    assert bind_address([("192.0.2.7", 9900)]) == "0.0.0.0"  # was 127.0.0.1, which cannot send to another host
    assert bind_address([("::1", 9900)]) == "::1"  # was an IPv4 socket: "cannot reach IPv6", hits dropped
    assert bind_address([("2001:db8::7", 9900), ("127.0.0.1", 9900)]) == "::"
    assert bind_address([("::1", 9900), ("127.0.0.1", 9900)]) == "::"


def _run_until(args: list[str], marker: str, tmp_path: Path) -> tuple[int, str]:
    """Run the CLI, press Ctrl-C once ``marker`` is printed; the exit status and stderr."""
    err_path = tmp_path / "stderr.txt"
    with err_path.open("w") as err:
        # SIGINT at its default: a suite run in the background (``cmd &``) ignores it, and so would the child
        proc = subprocess.Popen([sys.executable, "-m", "services.recogniser.cli", *args], cwd=ROOT,
                                stdout=subprocess.DEVNULL, stderr=err,
                                preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
        try:
            deadline = time.monotonic() + 60
            while marker not in err_path.read_text() and proc.poll() is None and time.monotonic() < deadline:
                time.sleep(0.05)
            proc.send_signal(signal.SIGINT)
            code = proc.wait(timeout=30)
        finally:
            if proc.poll() is None:
                proc.kill()
    return code, err_path.read_text()


def test_ctrl_c_stops_live_mode_and_keeps_what_was_heard(tmp_path: Path, pattern: Pattern) -> None:
    audio, out = tmp_path / "take.wav", tmp_path / "heard.mid"
    sf.write(audio, np.tile(pattern.audio, 4), pattern.sample_rate)  # long enough that Ctrl-C comes before its end
    code, err = _run_until([str(audio), "--live", "--to", "127.0.0.1:9", "-o", str(out)], "latency", tmp_path)
    assert code == 130 and "Traceback" not in err, err  # was a traceback and no MIDI file; then exit status 0
    assert "stopped (Ctrl-C)" in err and "hits sent" in err
    assert any(m.type == "note_on" for m in mido.MidiFile(out))


def test_ctrl_c_stops_a_transcription_cleanly(tmp_path: Path) -> None:
    audio, out = tmp_path / "long.wav", tmp_path / "long.mid"
    sf.write(audio, _clicks(600.0), 8000)
    code, err = _run_until([str(audio), "-o", str(out)], "transcribing", tmp_path)
    assert code == 130 and "Traceback" not in err, err
    assert "interrupted; nothing written" in err and not out.exists()


def test_the_recording_is_never_overwritten_by_its_transcription(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                                                  ) -> None:
    audio = tmp_path / "take.wav"
    sf.write(audio, _clicks(1.0), 8000)
    before = audio.read_bytes()
    assert main([str(audio), "-o", str(tmp_path / "." / "take.wav")]) == 2  # was: the WAV replaced by MIDI
    assert "is the audio file to transcribe" in capsys.readouterr().err and audio.read_bytes() == before


def test_a_live_run_behind_real_time_still_stops_when_cancelled(pattern_wav: Path) -> None:
    """Ctrl-C reaches a live run as a task cancellation at its next await: a run that falls behind real time
    (here: played 10^6 times faster) must still await between blocks, or it would play the whole file first."""
    from services.recogniser.node import LiveReport, play_file

    async def main() -> LiveReport:
        report = LiveReport()
        task = asyncio.ensure_future(play_file(pattern_wav, ["127.0.0.1:9"], speed=1e6, report=report,
                                               on_hit=lambda hit, latency: task.cancel()))
        with pytest.raises(asyncio.CancelledError):
            await task
        return report

    report = asyncio.run(main())
    whole = asyncio.run(play_file(pattern_wav, ["127.0.0.1:9"], speed=1e6))
    assert 1 <= len(report.hits) <= 3 < len(whole.hits)  # stopped at the first hit, not at the file's end
