"""What `batteur transcribe` tells a new user: a --live destination that refuses the hits, where --live -o
wrote the MIDI file, a summary that reads right for short files, and a file too short to transcribe."""

from __future__ import annotations

import re
import socket
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from services.recogniser.cli import main
from tests.ports import free_port

from .pattern import RATE, load_sample


@pytest.fixture
def listener() -> Iterator[socket.socket]:
    """A UDP socket on the loopback standing in for a node that receives the hits (in this process)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        sock.setblocking(False)
        yield sock


def _received(sock: socket.socket) -> int:
    count = 0
    while True:
        try:
            sock.recv(65536)
        except BlockingIOError:
            return count
        count += 1


def test_a_destination_nothing_listens_on_is_warned_about_once(pattern_wav: Path,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    target = f"127.0.0.1:{free_port()}"
    assert main([str(pattern_wav), "--live", "--speed", "50", "--to", target]) == 0
    err = capsys.readouterr().err
    hits = int(re.search(r"^(\d+) hits sent to", err, re.M).group(1))  # type: ignore[union-attr]
    warning = f"batteur transcribe: warning: --to {target}: the hits sent there are lost (Connection refused)"
    assert hits > 1 and err.count(warning) == 1, err  # was: "N hits sent", exit 0, no word of it


def test_a_destination_that_listens_gets_the_hits_and_no_warning(
        pattern_wav: Path, listener: socket.socket, capsys: pytest.CaptureFixture[str]) -> None:
    port = listener.getsockname()[1]
    nobody = f"127.0.0.1:{free_port()}"
    assert main([str(pattern_wav), "--live", "--speed", "50", "--to", f"127.0.0.1:{port}", "--to", nobody]) == 0
    err = capsys.readouterr().err
    hits = int(re.search(r"^(\d+) hits sent to", err, re.M).group(1))  # type: ignore[union-attr]
    assert _received(listener) == hits > 1  # every hit still arrives where something listens
    warnings = [line for line in err.splitlines() if "warning:" in line]
    assert len(warnings) == 1 and f"--to {nobody}:" in warnings[0], warnings  # only the one nobody hears


def test_live_says_where_it_wrote_the_midi_file(pattern_wav: Path, listener: socket.socket, tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "heard.mid"
    port = listener.getsockname()[1]
    assert main([str(pattern_wav), "--live", "--speed", "50", "--to", f"127.0.0.1:{port}", "-o", str(out)]) == 0
    last = capsys.readouterr().out.splitlines()[-1]  # where the file went: stdout (was stderr), as render's
    assert re.fullmatch(rf"\d+ notes \(kick \d+, snare \d+.*\), tempo .* -> {re.escape(str(out))}", last), last
    assert out.is_file()


def _snare(tmp_path: Path, seconds: float) -> Path:
    path = tmp_path / "snare.wav"
    sf.write(path, load_sample("snare")[: int(seconds * RATE)], RATE)
    return path


def test_a_short_file_s_summary_reads_right(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "snare.mid"
    assert main([str(_snare(tmp_path, 0.25)), "-o", str(out)]) == 0
    line = capsys.readouterr().out.strip()
    # was "1 notes (snare 1) from 0.2 s of audio in 0.12 s (2x real time)" (and "0x" for shorter files)
    assert re.fullmatch(rf"1 note \(snare 1\) from 250 ms of audio in \d+\.\d\d s, tempo 120 bpm \(.*\) -> "
                        rf"{re.escape(str(out))}",
                        line), line


def test_a_long_file_s_summary_keeps_its_real_time_factor(pattern_wav: Path, tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    assert main([str(pattern_wav), "-o", str(tmp_path / "p.mid")]) == 0
    line = capsys.readouterr().out.strip()
    assert re.fullmatch(r"\d+ notes \(.*\) from \d+\.\d s of audio in \d+\.\d\d s \((\d+|0\.\d+)x real time\), "
                        r"tempo .* -> .*p\.mid", line), line


@pytest.mark.parametrize("live", [False, True])
def test_a_file_under_one_frame_is_too_short_not_silent(tmp_path: Path, live: bool,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "one.wav"
    sf.write(path, np.full(1, 0.5, np.float32), RATE)
    args = ["--live", "--to", f"127.0.0.1:{free_port()}"] if live else ["-o", str(tmp_path / "one.mid")]
    assert main([str(path), *args]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"batteur transcribe: error: {path}: too short to transcribe: 1 sample (0.0227 ms); the "
                          "minimum is 10 ms") and "silent" not in err, err  # was "silent but for a constant offset"


def test_a_file_of_one_frame_is_transcribed(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main([str(_snare(tmp_path, 0.01)), "-o", str(tmp_path / "snare.mid")]) == 0  # 441 samples: the minimum
    assert "from 10 ms of audio" in capsys.readouterr().out
