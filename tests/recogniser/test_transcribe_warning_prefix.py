"""`batteur transcribe`'s warnings begin with the command's name, as its errors and the other commands' warnings
do (`batteur render: warning: ...`): they were `warning: ...` of no command."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from services.recogniser.cli import main


def test_a_warning_names_the_command(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    clicks = np.zeros(16000, np.float32)
    clicks[::4000] = 0.9  # a click every half second, 2 s at 8 kHz
    whole = tmp_path / "whole.wav"
    sf.write(whole, clicks, 8000, subtype="PCM_16")
    cut = tmp_path / "cut.wav"
    cut.write_bytes(whole.read_bytes()[: 44 + 8000 * 2])  # the header still announces 2 s; 1 s is there
    assert main([str(cut), "-o", str(tmp_path / "cut.mid")]) == 0
    warnings = [line for line in capsys.readouterr().err.splitlines() if "warning:" in line]
    assert warnings and all(line.startswith("batteur transcribe: warning: ") for line in warnings), warnings
