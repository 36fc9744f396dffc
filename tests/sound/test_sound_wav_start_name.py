"""--wav's {start} placeholder: each take its own file, named when recording starts; other paths as before."""

from __future__ import annotations

from datetime import datetime
from pathlib import Path

import pytest
import soundfile as sf

from services.sound.node import expand_wav_path, main

NOW = datetime(2026, 1, 31, 20, 15, 0)


def test_start_is_the_local_time_and_a_taken_name_gets_a_number(tmp_path: Path) -> None:
    template = tmp_path / "batteur-{start}.wav"
    first = expand_wav_path(template, NOW)
    assert first == tmp_path / "batteur-20260131-201500.wav"
    sf.write(first, [0.0] * 10, 48000)
    second = expand_wav_path(template, NOW)  # a second take in the same second
    assert second == tmp_path / "batteur-20260131-201500-2.wav"
    # a node still recording it holds the name too (its hidden part file), as does a take's .json alone
    (tmp_path / ".batteur-20260131-201500-2.wav.abcd1234.part").touch()
    (tmp_path / "batteur-20260131-201500-3.wav.json").touch()
    assert expand_wav_path(template, NOW) == tmp_path / "batteur-20260131-201500-4.wav"


def test_a_path_without_the_placeholder_is_used_as_written(tmp_path: Path) -> None:
    take = tmp_path / "take.wav"
    sf.write(take, [0.0] * 10, 48000)
    assert expand_wav_path(take, NOW) == take  # replaced at the end, as always (the rig's performance.wav)
    odd = tmp_path / "{dir}" / ".performance.part.wav"  # braces in folders are not placeholders
    assert expand_wav_path(odd, NOW) == odd
    assert expand_wav_path(tmp_path / "take{{1}}.wav", NOW) == tmp_path / "take{1}.wav"


@pytest.mark.parametrize(("name", "says"), [
    ("take-{foo}.wav", "unknown placeholder {foo}: the only one is {start}, the take's start time"),
    ("take-{start:%Y}.wav", "unknown placeholder {start:%Y}: the only one is {start}"),
    ("take-{start.wav", "in the file name (a brace is written {{ or }})"),
])
@pytest.mark.timeout(120)  # was: accepted, and the node ran (recording to a file named take-{foo}.wav)
def test_a_bad_placeholder_is_one_line_before_start(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                     name: str, says: str) -> None:
    assert main(["--no-discovery", "--no-oscquery", "--device", "none", "--wav", str(tmp_path / name)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"batteur sound: error: --wav {tmp_path / name}: ") and says in err, err
    assert len(err.splitlines()) == 1
    assert list(tmp_path.iterdir()) == []


def test_help_says_what_start_becomes(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["--help"])
    text = "".join(capsys.readouterr().out.split())  # argparse may wrap at any space or hyphen
    assert "".join("{start} in the file name is the take's start time, local YYYYmmdd-HHMMSS".split()) in text
